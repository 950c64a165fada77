"""``python -m foldmatch_rs`` and the ``foldmatch`` console script.

Both run the Rust ``foldmatch`` command line program compiled into the extension (the same code
as the standalone binary, ``src/cli``), so there is one implementation. See ``foldmatch --help``
and ``docs/cli.md``. ``batch`` and ``sequence`` with ``--scheduler ADDRESS|local`` run their
fits on a Dask cluster (``foldmatch_rs.distributed``, docs/cluster.md).
"""

from __future__ import annotations

import sys

from ._foldmatch_rs import cluster_request, run_cli


def main() -> None:
    """Run ``foldmatch`` with this process's arguments and exit with its status."""
    sys.stdout.flush()
    sys.stderr.flush()
    argv = ["foldmatch", *sys.argv[1:]]
    on_cluster = cluster_request(argv)
    if on_cluster is not None:
        from ._cluster_cli import run_on_cluster

        sys.exit(run_on_cluster(on_cluster))
    sys.exit(run_cli(argv))


if __name__ == "__main__":
    main()
