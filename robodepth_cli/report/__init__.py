"""`robodepth report`: the paper's tables and figures for any number of models (HTML page, figures, LaTeX, Markdown, scores.json). Light: submodules import what they need."""
