"""`python -m mjkdl.menagerie`: where Menagerie models come from and which are here."""

from __future__ import annotations

import sys

from . import report


def main() -> int:
    """Print the report; exit 1 when `MENAGERIE_ROOT` points nowhere."""
    text, usable = report()
    print(text, file=sys.stdout if usable else sys.stderr)
    return 0 if usable else 1


if __name__ == "__main__":
    raise SystemExit(main())
