"""The locked install (``constraints.txt`` in this package, a pip constraints file): the
exact version of every distribution that decides a pixel, and how a set of versions (a
build's record, or the installed ones) differs from it.

``make install`` installs with ``-c`` on this one file; ``robodepth verify`` and
``robodepth selftest`` read it at run time, so a wheel carries it as package data.
"""

from __future__ import annotations

import re
from pathlib import Path

LOCK_FILE = Path(__file__).resolve().with_name("constraints.txt")
NOT_INSTALLED = "not installed"

_PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s;#]+)\s*(?:#.*)?$")


def canonical(name: str) -> str:
    """A distribution's name as pip compares them (``Pillow`` and ``pillow``, ``PyYAML``
    and ``pyyaml`` are the same distribution)."""
    return re.sub(r"[-_.]+", "-", name).lower()


def locked(path: Path | None = None) -> dict[str, str]:
    """``{name: version}`` of every ``name==version`` line of the lock, in file order."""
    pins = {}
    for line in (path or LOCK_FILE).read_text(encoding="utf-8").splitlines():
        m = _PIN.match(line.strip())
        if m:
            pins[m.group(1)] = m.group(2)
    return pins


def installed(names) -> dict[str, str]:
    """``{name: version}`` of the installed distributions ``names`` (``"not installed"``
    for a missing one), read from package metadata without importing them."""
    from importlib import metadata

    found = {}
    for name in names:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = NOT_INSTALLED
    return found


def _release(version: str) -> str:
    # torch's wheels carry their build in a local label (2.13.0+cpu, 2.13.0+cu128): the
    # lock pins the release, as pip's ``torch==2.13.0`` does.
    return version.split("+", 1)[0]


def differences(versions: dict[str, str], lock: dict[str, str] | None = None, *,
                missing: bool = False) -> list[str]:
    """``"numpy 2.3.0 (lock 2.4.6)"`` for each locked distribution whose version in
    ``versions`` differs from the lock's. A distribution ``versions`` does not name, or
    names as not installed, counts only with ``missing`` (an install that lacks it)."""
    lock = locked() if lock is None else lock
    have = {canonical(k): v for k, v in versions.items()}
    out = []
    for name, want in lock.items():
        got = have.get(canonical(name), NOT_INSTALLED)
        if got == NOT_INSTALLED:
            if missing:
                out.append(f"{name} {NOT_INSTALLED} (lock {want})")
        elif _release(got) != _release(want):
            out.append(f"{name} {got} (lock {want})")
    return out


def build_note(versions: dict[str, str]) -> str:
    """One line for a build whose recorded ``versions`` differ from the lock's ("" when they
    do not): it may not hold the reference bytes."""
    diff = differences(versions)
    if not diff:
        return ""
    return (f"built with other versions than the lock ({'; '.join(diff)}): the build may not "
            f"be the reference bytes")
