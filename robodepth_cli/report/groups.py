"""Variants of one model compared per corruption (the paper's Figs. 3 and 4): for a property P
(``modality``, ``pretrain``, ``resolution``), a group is every model whose base and other
properties are equal, when it holds at least two values of P. A published model's
properties are its table's columns, its base the first word of its name; a user's model's
are its ``--tag`` values (docs/report.md)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

from .published import PROPERTIES as ALL

COMPARED = ("modality", "pretrain", "resolution")
TITLES = {"modality": "Training modality", "pretrain": "Pre-training", "resolution": "Input resolution"}


@dataclass(frozen=True)
class Member:
    name: str
    mine: bool
    base: str
    props: dict
    scores: object  # evaluation.scores.Scores


@dataclass
class Group:
    prop: str
    base: str
    fixed: tuple[tuple[str, str], ...]  # the other properties' values
    members: list[Member] = field(default_factory=list)

    @property
    def title(self) -> str:
        # The published file writes "None" for a model trained from scratch.
        fixed = ", ".join("no pre-training" if k == "pretrain" and v == "None" else v
                          for k, v in self.fixed if v)
        return (self.base or "your models") + (f" ({fixed})" if fixed else "")


def members(models: Sequence, tags: dict[str, dict[str, str]], context: Sequence,
            benchmark: str) -> list[Member]:
    """The user's ``models`` (scored, with their tags) then the published rows of
    ``context`` (with the published columns)."""
    from .published import properties

    out = []
    for m in models:
        s = m.row.scores
        if s is None or s.note:
            continue
        t = tags.get(m.name, {})
        out.append(Member(m.name, True, t.get("base", ""), {k: t[k] for k in ALL if k in t}, s))
    props = properties(benchmark) if benchmark == "kitti-c" else {}
    for r in context:
        if r.name in props and r.scores is not None:
            out.append(Member(r.name, False, r.name.split()[0], props[r.name], r.scores))
    return out


def groups(pool: Sequence[Member]) -> dict[str, list[Group]]:
    """Per compared property, its groups (module docstring), members in ``pool`` order."""
    out: dict[str, list[Group]] = {}
    for prop in COMPARED:
        found: dict[tuple, Group] = {}
        for m in pool:
            if prop not in m.props:
                continue
            fixed = tuple((k, m.props.get(k, "")) for k in ALL if k != prop)
            found.setdefault((m.base, fixed), Group(prop, m.base, fixed)).members.append(m)
        kept = [g for g in found.values() if len({m.props[prop] for m in g.members}) > 1]
        if kept:
            out[prop] = kept
    return out


def figure(prop: str, found: Sequence[Group], benchmark: str):
    """CE per corruption, one panel per group, one bar per variant in each corruption's
    place (benchmark order, a gap between categories), coloured by the property's value
    (the same value the same colour in every panel); the baseline's 100% dashed."""
    from ..benchmark_facts import CATEGORIES
    from . import plot

    first = found[0].members[0].scores
    names = [c.name for c in first.corruptions]
    xs, x = {}, 0.0
    for cat in CATEGORIES:
        for c in first.corruptions:
            if c.category == cat:
                xs[c.name] = x
                x += 1.0
        x += 0.6
    values = list(dict.fromkeys(m.props[prop] for g in found for m in g.members))
    colour = {v: plot.OKABE_ITO[i % len(plot.OKABE_ITO)] for i, v in enumerate(values)}
    fig = plot.new_figure(11.0, 1.5 + 2.1 * len(found) + 0.9)
    axes = fig.subplots(len(found), 1, sharex=True, squeeze=False)[:, 0]
    top = max(c.ce for g in found for m in g.members for c in m.scores.corruptions if c.ce is not None)
    for ax, g in zip(axes, found):
        width = 0.8 / len(g.members)
        for i, m in enumerate(g.members):
            by = {c.name: c for c in m.scores.corruptions}
            pos = [xs[n] - 0.4 + width * (i + 0.5) for n in names]
            ce = [by[n].ce if n in by and by[n].ce is not None else 0.0 for n in names]
            ax.bar(pos, ce, width=width * 0.92, color=colour[m.props[prop]], antialiased=False,
                   label=f"{m.props[prop]}: {m.name}  (mCE {m.scores.overall.ce:.1f})")
        ax.axhline(100.0, color=plot.INK, linestyle=(0, (4, 3)), linewidth=1.0, zorder=3)
        ax.set_ylim(0, max(125.0, top * 1.08))
        ax.set_ylabel("CE (%)")
        ax.set_title(g.title, fontsize=9.5, loc="left", color=plot.INK)
        ax.grid(axis="y", color="#e4e4e4", linewidth=0.8)
        ax.set_axisbelow(True)
        for side in ("top", "right"):
            ax.spines[side].set_visible(False)
        legend = ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False, fontsize=8.5)
        for text, m in zip(legend.get_texts(), g.members):
            if m.mine:
                text.set_fontweight("bold")
    axes[-1].set_xticks([xs[n] for n in names], [plot.pretty(n) for n in names], rotation=90,
                        fontsize=8.5)
    axes[-1].set_xlim(-0.7, x - 0.6 - 0.3)
    plot.figure_title(fig, f"{TITLES[prop]}: CE per corruption on {plot.bench_title(benchmark)}",
                      f"variants of one model that differ in {TITLES[prop].lower()} only; "
                      f"baseline {first.baseline.name} = 100% (dashed); bold: your models")
    return fig
