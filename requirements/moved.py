"""Which packages of an environment differ from the lock: ``python requirements/moved.py LOCK FREEZE``.

LOCK is ``requirements/test.lock`` (``uv pip compile`` output), FREEZE what ``pip freeze`` printed
for the environment under test. One line per package whose version moved, was added or is not
installed, so that a red ``make test-latest`` says which release to look at first. Exit 0.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

from packaging.markers import Marker
from packaging.utils import canonicalize_name


def _pins(text: str, locked: bool) -> dict[str, str]:
    out: dict[str, str] = {}
    for line in text.splitlines():
        m = re.match(r"^([A-Za-z0-9_.\-]+)(?:\[[^\]]*\])?==([^\s;\\]+)\s*(?:;\s*([^\\]+))?", line)
        if not m:
            continue
        name, version, marker = m.groups()
        if locked and marker and not Marker(marker.strip()).evaluate():
            continue  # another platform's or Python's pin
        out[canonicalize_name(name)] = version
    return out


def main(lock: str, freeze: str) -> int:
    locked = _pins(Path(lock).read_text(), True)
    now = _pins(Path(freeze).read_text(), False)
    moved = [(n, locked.get(n, "—"), now.get(n, "not installed")) for n in sorted(set(locked) | set(now))]
    moved = [m for m in moved if m[1] != m[2] and m[0] != "pip"]
    print(f"{len(moved)} of {len(now)} packages differ from {lock}" + (":" if moved else ""))
    for name, a, b in moved:
        print(f"  {name:32s} {a:>14s} → {b}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        print("usage: python requirements/moved.py LOCK FREEZE", file=sys.stderr)
        sys.exit(2)
    sys.exit(main(*sys.argv[1:]))
