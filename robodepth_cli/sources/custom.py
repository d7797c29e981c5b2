"""``robodepth build custom``: any folder of images as a dataset.

Instead of a split, the sources are found under the root:

* every file whose path relative to the root matches one of the patterns (default
  :data:`DEFAULT_PATTERNS`: png, jpg, jpeg, bmp, tif, tiff and webp files at any depth),
  sorted by that path; or
* with ``--list FILE``, exactly the paths listed there (one relative path a line; blank
  lines and ``#`` comments ignored), in that order.

Each source's key (the name of its outputs and the path that seeds its jobs) is its path
relative to the root with its extension replaced by ``.png`` (:func:`sourcekeys.custom_key`).
Two sources with the same key (``a.jpg`` and ``a.png``) are refused before any work.

Pattern syntax (matched against the posix path relative to the root, case-insensitively):
``*`` any characters within one path component, ``?`` one such character, ``[abc]`` /
``[a-z]`` / ``[!abc]`` one of a set, and ``**`` as a whole component any number of
directories (including none). Patterns are comma-separated. Anything else that looks like
syntax (``{a,b}``, ``**`` inside a component, an unclosed ``[``) and absolute or ``..``
patterns are refused.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from ..errors import InvalidValueError, RobodepthError, os_reason
from ..sourcekeys import custom_key, relative_parts

IMAGE_EXTS = ("png", "jpg", "jpeg", "bmp", "tif", "tiff", "webp")
DEFAULT_PATTERNS = tuple(f"**/*.{e}" for e in IMAGE_EXTS)


class CustomSourceError(RobodepthError):
    """A custom build's sources cannot be found as asked (bad pattern or list, no match,
    colliding keys)."""


# --- patterns ----------------------------------------------------------------------------

def _component_regex(comp: str, pattern: str) -> str:
    out, i = [], 0
    while i < len(comp):
        ch = comp[i]
        if ch == "*":
            if comp.startswith("**", i):
                raise InvalidValueError(f"pattern {pattern!r}: '**' must be a whole path component (a/**/b)")
            out.append("[^/]*")
        elif ch == "?":
            out.append("[^/]")
        elif ch == "[":
            end = comp.find("]", i + 2 if comp.startswith("[!", i) or comp.startswith("[]", i) else i + 1)
            if end < 0:
                raise InvalidValueError(f"pattern {pattern!r}: unclosed '['")
            body = comp[i + 1:end]
            neg = body.startswith("!")
            body = body[1:] if neg else body
            if not body:
                raise InvalidValueError(f"pattern {pattern!r}: empty character set")
            out.append("[" + ("^" if neg else "") + body.replace("\\", "\\\\").replace("^", "\\^") + "]")
            i = end
        elif ch in "{}":
            raise InvalidValueError(f"pattern {pattern!r}: braces are not supported; give several "
                             f"comma-separated patterns instead")
        elif ch == "]":
            raise InvalidValueError(f"pattern {pattern!r}: ']' without '['")
        else:
            out.append(re.escape(ch))
        i += 1
    return "".join(out)


def compile_pattern(pattern: str) -> re.Pattern:
    """A regular expression matching the relative posix paths that ``pattern`` selects;
    :class:`InvalidValueError` describing the problem for unsupported syntax."""
    p = pattern.strip()
    if not p:
        raise InvalidValueError("empty pattern")
    if p.startswith("/") or "\\" in p or "\0" in p:
        raise InvalidValueError(f"pattern {pattern!r}: must be a relative path with '/' separators")
    comps = p.split("/")
    if any(c in ("", ".", "..") for c in comps):
        raise InvalidValueError(f"pattern {pattern!r}: has an empty, '.' or '..' component")
    if comps[-1] == "**":
        raise InvalidValueError(f"pattern {pattern!r}: must end with a file name pattern (e.g. **/*.png)")
    rx = ""
    for c in comps[:-1]:
        rx += "(?:[^/]+/)*" if c == "**" else _component_regex(c, pattern) + "/"
    rx += _component_regex(comps[-1], pattern)
    return re.compile(rx, re.IGNORECASE | re.DOTALL)


def parse_patterns(text) -> tuple[str, ...]:
    """Comma-separated text or a list -> the patterns, each checked by :func:`compile_pattern`."""
    if isinstance(text, str) and ("{" in text or "}" in text):
        raise InvalidValueError(f"pattern {text!r}: braces are not supported; give several "
                         f"comma-separated patterns instead (e.g. '**/*.jpg,**/*.png')")
    items = text.split(",") if isinstance(text, str) else text
    if not isinstance(items, (list, tuple)) or not items:
        raise InvalidValueError(f"expected comma-separated patterns such as '**/*.jpg,**/*.png', got {text!r}")
    out = []
    for item in items:
        if not isinstance(item, str):
            raise InvalidValueError(f"expected a pattern, got {item!r}")
        compile_pattern(item)
        out.append(item.strip())
    return tuple(dict.fromkeys(out))


def check_list(value, base: Path) -> str | None:
    """The checked ``list`` (a file, relative to ``base``) as an absolute path."""
    if value is None:
        return None
    if not isinstance(value, str) or not value.strip():
        raise InvalidValueError(f"expected a file listing one relative image path a line, got {value!r}")
    return str((base / Path(value).expanduser()).resolve())


# --- discovery ---------------------------------------------------------------------------

def discover(root: Path, patterns, exclude=()) -> list[str]:
    """The relative posix paths of the files under the resolved directory ``root`` that
    match ``patterns``, sorted. Directory symlinks are followed (each real directory
    once); the directories ``exclude`` are not entered (a build refuses an OUT inside the
    root before looking for sources; this keeps the walk out of it all the same, and out
    of a --depth directory inside the root, whose PNG maps are no images)."""
    regexes = [compile_pattern(p) for p in patterns]
    seen_dirs: set[str] = set()
    skip = {os.path.realpath(e) for e in exclude if e is not None}
    found = []
    for dirpath, dirnames, filenames in os.walk(root, followlinks=True):
        real = os.path.realpath(dirpath)
        if real in seen_dirs or real in skip:
            dirnames[:] = []
            continue
        seen_dirs.add(real)
        rel_dir = os.path.relpath(dirpath, root).replace(os.sep, "/")
        prefix = "" if rel_dir == "." else rel_dir + "/"
        for name in filenames:
            rel = prefix + name
            if any(rx.fullmatch(rel) for rx in regexes):
                found.append(rel)
        dirnames.sort()
    return sorted(found)


def read_list(path: Path) -> list[tuple[int, str]]:
    """``(line number, relative path)`` of every entry of a ``--list`` file."""
    try:
        text = Path(path).read_text(encoding="utf-8-sig")  # a byte-order mark, as in split files
    except UnicodeDecodeError:
        raise CustomSourceError(f"{path}: not a text file") from None
    except OSError as exc:
        raise CustomSourceError(f"{path}: cannot read the list ({os_reason(exc)})") from None
    out, seen = [], {}
    for n, line in enumerate(text.splitlines(), 1):
        rel = line.strip()
        if not rel or rel.startswith("#"):
            continue
        try:
            relative_parts(rel, "path")
        except InvalidValueError as exc:
            raise CustomSourceError(f"{path}:{n}: {exc}; list paths relative to --root, "
                                    f"inside it") from None
        if rel in seen:
            raise CustomSourceError(f"{path}:{n}: duplicate of line {seen[rel]} ({rel})")
        seen[rel] = n
        out.append((n, rel))
    if not out:
        raise CustomSourceError(f"{path}: the list names no images")
    return out


def check_keys(rels, where: str) -> list[str]:
    """The key of each relative path; :class:`CustomSourceError` when two share one."""
    first: dict[str, str] = {}
    keys = []
    for rel in rels:
        key = custom_key(rel)
        if key in first:
            raise CustomSourceError(f"{where}: {first[key]} and {rel} would both be written as "
                                    f"{key}; rename one or leave it out (--pattern or --list)")
        first[key] = rel
        keys.append(key)
    return keys


def find_sources(root: Path, cfg, out: Path | None = None, split_patterns: str | None = None):
    """The sources of a custom build: ``(list of (key, rel), split record)`` where the
    record describes how they were found (for ``build.json``). ``split_patterns``: those of
    a preset's named split, used unless ``pattern`` or ``list`` is given."""
    from ..files import sha256_bytes

    listed = cfg.options.list
    depth = cfg.options.depth
    if depth and not Path(depth).is_dir():
        raise CustomSourceError(f"{depth}: the depth directory (--depth) does not exist")
    patterns = (cfg.options.pattern or (split_patterns and parse_patterns(split_patterns))
                or DEFAULT_PATTERNS)
    if listed and cfg.options.pattern:
        raise CustomSourceError("--pattern and --list both given: the list alone says which images "
                                "to build; give one of them")
    if listed:
        rels = [rel for _, rel in read_list(Path(listed))]
        where = str(listed)
        record = {"path": str(listed), "sha256": sha256_bytes(Path(listed).read_bytes())}
    else:
        rels = discover(root, patterns, exclude=(out, depth))
        if not rels:
            raise CustomSourceError(f"{root}: no file matches {','.join(patterns)} (use --pattern "
                                    f"to choose others)")
        where = str(root)
        record = {"path": None, "sha256": None, "patterns": list(patterns)}
    keys = check_keys(rels, where)[: cfg.limit]
    rels = rels[: cfg.limit]
    record.update(images=len(rels), keys=keys)
    return list(zip(keys, rels)), record
