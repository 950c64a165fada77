"""``python -m foldmatch_rs`` and the ``foldmatch`` console script.

Both run the Rust ``foldmatch`` command line program compiled into the extension (the same code
as the standalone binary, ``src/cli``), so there is one implementation. See ``foldmatch --help``
and ``docs/cli.md``.
"""

from __future__ import annotations

import sys

from ._foldmatch_rs import run_cli


def main() -> None:
    """Run ``foldmatch`` with this process's arguments and exit with its status."""
    sys.stdout.flush()
    sys.stderr.flush()
    sys.exit(run_cli(["foldmatch", *sys.argv[1:]]))


if __name__ == "__main__":
    main()
