"""Fit a batch of scans, or track 4D sequences, on a Dask cluster (``pip install
'dask[distributed]>=2023.1'`` next to the package; docs/cluster.md).

Each scan (each frame of a sequence) is one Dask task that reads, fits and writes its output
(staged) on the worker, with the Rust code of ``foldmatch batch`` / ``foldmatch sequence``; the
submitting process renames it into place once ``report.json`` records it, as those commands do:
the files are those commands' bit for bit, whatever the number of workers, and the returned
report is their ``report.json`` (written there too, and kept up to date as tasks finish).
Workers must see the paths the driver sees (one machine, or shared storage); paths are made
absolute before they are sent.

``client`` chooses the cluster: ``None`` or ``"local"`` starts a ``LocalCluster`` of worker
processes on this machine (one per core, closed at the end), an address
(``"tcp://host:8786"``) connects to a running scheduler, a ``distributed.Client`` is used as
it is. A task whose worker dies (killed, out of memory) is run again on another worker (Dask
allows ``distributed.scheduler.allowed-failures`` deaths per task; a local cluster started
here allows ``retries``), a task that raises is retried ``retries`` times, and a file that
cannot be fitted is an ``error`` entry of the report while the others go on. See
``docs/cluster.md``.

Examples
--------
>>> from foldmatch_rs.distributed import fit_batch  # doctest: +SKIP
>>> report = fit_batch("template.ply", "scans/", "fitted/", iterations=50)  # doctest: +SKIP
>>> report["summary"]  # doctest: +SKIP
{'total': 120, 'ok': 119, 'error': 1, 'skipped': 0, 'interrupted': 0, 'pending': 0}
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import uuid
from typing import Any, Iterator, Optional, Sequence, Union

try:
    import dask
    from distributed import Client, Future, KilledWorker, LocalCluster, as_completed
except ImportError as _missing:  # pragma: no cover - depends on the installed extras
    raise ImportError(
        "foldmatch_rs.distributed needs Dask's distributed scheduler: pip install 'dask[distributed]>=2023.1'"
    ) from _missing

from . import _foldmatch_rs as _core
from ._cluster_tasks import Threads, fit_file, track_frame
from .errors import InvalidParameterError
from .params import FitParams

PathLike = Union[str, "os.PathLike[str]"]
#: A ``distributed.Client``, a scheduler address, or ``None`` / ``"local"`` for a local cluster.
ClientLike = Union[Client, str, None]

#: How often a task is run again after it raised (and, on a local cluster started here, after
#: its worker died).
DEFAULT_RETRIES = 3


def fit_batch(
    template: PathLike,
    scans: Union[PathLike, Sequence[PathLike]],
    out_dir: PathLike,
    *,
    client: ClientLike = None,
    resume: bool = False,
    preset: str = "default",
    recursive: bool = False,
    glob: Optional[str] = None,
    format: str = "ply",
    ascii: bool = False,
    gt_dir: Optional[PathLike] = None,
    threads: Optional[int] = None,
    workers: Optional[int] = None,
    retries: int = DEFAULT_RETRIES,
    progress: bool = False,
    **params: Any,
) -> dict[str, Any]:
    """Fit ``template`` to every scan on a Dask cluster, as ``foldmatch batch`` does.

    Parameters
    ----------
    template : path
        The template mesh (.ply / .obj with faces).
    scans : path or list of paths
        A folder (every .ply / .obj file, natural order; ``recursive`` and ``glob`` as the
        command's options) or a list of scan files (named by their path relative to the folder
        that holds them all).
    out_dir : path
        Output folder: ``out_dir/<name>.<format>`` per scan and ``out_dir/report.json``.
    client : distributed.Client, str or None
        The cluster (see the module's documentation).
    resume : bool
        Skip the scans whose output exists and whose entry in ``report.json`` is ok.
    preset, **params
        The fit settings: a preset, and settings by name or as ``params=`` (a
        :class:`~foldmatch_rs.FitParams`, which carries its preset, or a dict), as
        :func:`foldmatch_rs.fit` takes them.
    format, ascii, gt_dir
        As ``foldmatch batch --format / --ascii / --gt-dir``.
    threads : int, optional
        Fit threads per task; by default each machine's cores shared by its workers' task
        slots, so workers do not oversubscribe the cores.
    workers : int, optional
        Worker processes of a local cluster started here (default: one per core).
    retries : int
        Runs again of a task that raised or, on a local cluster started here, whose worker died.
    progress : bool
        Print the batch's log lines and progress bar on standard error (else only errors).

    Returns
    -------
    dict
        The report, as written to ``out_dir/report.json`` (the schema of ``foldmatch batch``'s):
        ``summary`` counts the statuses, ``files`` has one entry per scan (``ok``, ``error``
        with the reason, or ``skipped``).

    Raises
    ------
    RunSetupError
        The batch could not start (unreadable template, no scans, invalid parameters).
    ImportError
        ``dask[distributed]`` is not installed.
    """
    request = _request(
        "batch",
        template,
        scans,
        out_dir,
        resume=resume,
        preset=preset,
        recursive=recursive,
        glob=glob,
        format=format,
        ascii=ascii,
        gt_dir=gt_dir,
        params=params,
    )
    book = _book(request, progress)
    with connect(client, workers=workers, retries=retries) as c:
        ((_, report),) = run_books(c, "batch", [book], ascii=ascii, threads=threads, retries=retries)
    return report


def track_sequences(
    template: PathLike,
    sequence_dirs: Sequence[PathLike],
    out_dir: PathLike,
    *,
    client: ClientLike = None,
    resume: bool = False,
    preset: str = "tracking",
    glob: Optional[str] = None,
    format: str = "ply",
    ascii: bool = False,
    gt_dirs: Optional[Sequence[Optional[PathLike]]] = None,
    threads: Optional[int] = None,
    workers: Optional[int] = None,
    retries: int = DEFAULT_RETRIES,
    progress: bool = False,
    prediction: Optional[float] = None,
    reanchor: bool = False,
    **params: Any,
) -> dict[str, dict[str, Any]]:
    """Track many 4D sequences in parallel on a Dask cluster, each as ``foldmatch sequence``.

    Each sequence is one chain of tasks: its frames are fitted in natural order, each
    warm-started from the previous frame's fit; the chains of different sequences run at the
    same time. Sequence ``frames/walk`` goes to ``out_dir/walk/`` with its own ``report.json``
    (the schema of ``foldmatch sequence``'s); two sequence folders must not share a name.

    ``gt_dirs`` gives, per sequence, a folder of ground-truth meshes named like its frames (or
    ``None``). ``prediction`` and ``reanchor`` are the tracking rules of ``foldmatch
    sequence --prediction/--reanchor`` (:func:`foldmatch_rs.track`'s; each frame continues
    the same tracker as the local command, so the outputs are its outputs bit for bit). The
    other parameters are those of :func:`fit_batch`; the default preset is ``"tracking"``, as
    for ``foldmatch sequence``.

    Returns ``{sequence name: report}``.
    """
    dirs = [os.fspath(d) for d in sequence_dirs]
    names = [os.path.basename(os.path.normpath(d)) for d in dirs]
    if len(set(names)) != len(names):
        raise InvalidParameterError(f"two sequence folders share a name: {names}")
    if gt_dirs is not None and len(gt_dirs) != len(dirs):
        raise InvalidParameterError("gt_dirs: one entry per sequence folder")
    books = []
    for k, (d, name) in enumerate(zip(dirs, names)):
        request = _request(
            "sequence",
            template,
            d,
            os.path.join(os.fspath(out_dir), name),
            resume=resume,
            preset=preset,
            recursive=False,
            glob=glob,
            format=format,
            ascii=ascii,
            gt_dir=None if gt_dirs is None else gt_dirs[k],
            params=params,
        )
        request["tracking"] = {"reanchor": bool(reanchor)}
        if prediction is not None:
            request["tracking"]["prediction"] = float(prediction)
        books.append(_book(request, progress))
    with connect(client, workers=workers, retries=retries) as c:
        results = run_books(c, "sequence", books, ascii=ascii, threads=threads, retries=retries)
    return {name: report for name, (_, report) in zip(names, results)}


@contextlib.contextmanager
def connect(
    client: ClientLike = None, *, workers: Optional[int] = None, retries: int = DEFAULT_RETRIES
) -> Iterator[Client]:
    """A Dask client for ``client`` (see the module's documentation); what is started here is
    closed on exit. A local cluster has ``workers`` worker processes (default: one per core)
    of one task slot each, and allows ``retries`` worker deaths per task."""
    if isinstance(client, Client):
        yield client
        return
    if client is None or client == "local":
        with dask.config.set({"distributed.scheduler.allowed-failures": int(retries)}):
            cluster = LocalCluster(
                n_workers=workers or _cores(),
                threads_per_worker=1,
                processes=True,
                dashboard_address=":0",  # any free port: never a warning about 8787
                silence_logs=logging.ERROR,
            )
        try:
            with Client(cluster) as local:
                yield local
        finally:
            cluster.close()
        return
    if isinstance(client, str):
        with Client(client) as remote:
            yield remote
        return
    raise InvalidParameterError(
        f"client: expected a distributed.Client, a scheduler address or None, got {client!r}"
    )


def run_books(
    client: Client,
    kind: str,
    books: Sequence[Any],
    *,
    ascii: bool,
    threads: Optional[int],
    retries: int,
) -> list[tuple[int, dict[str, Any]]]:
    """Runs planned runs (``RunBook``) on ``client``: every file of a batch as an independent
    task, every sequence as a chain of tasks; records each file in its run's report as its
    future completes. Returns ``(exit code, report)`` per run (the exit codes of the
    ``foldmatch`` command). On Ctrl-C the tasks are cancelled, the reports written as
    interrupted and ``KeyboardInterrupt`` raised again."""
    slots = task_threads(client, threads)
    tag = uuid.uuid4().hex[:8]
    owner: dict[Future, tuple[Any, int]] = {}
    for b, book in enumerate(books):
        files = json.loads(book.files_json())
        what = "scans" if kind == "batch" else "frames"
        book.info(f"{kind}: {book.total} {what}, {len(files)} to fit, on {_describe(client, slots)}")
        previous: Optional[Future] = None
        for file in files:
            key = f"foldmatch-{kind}-{tag}-{b}-{file['index']}"
            common = (book.template, book.params_json, json.dumps(file), ascii, slots)
            if kind == "batch":
                future = client.submit(fit_file, *common, key=key, retries=retries, pure=False)
            else:
                future = client.submit(
                    track_frame, *common, book.tracking_json, previous, key=key, retries=retries, pure=False
                )
                previous = future
            owner[future] = (book, file["index"])
    interrupted = False
    try:
        pending = as_completed(list(owner), raise_errors=False)
        for future in pending:
            if future.status not in ("finished", "error", "cancelled"):
                # Completed on a worker that died before the result was read: the scheduler
                # recomputes it elsewhere, so wait for it again.
                pending.add(future)
                continue
            book, index = owner.pop(future)
            if future.status != "finished":
                book.record_failure(index, _failure(future))
                continue
            try:
                result = future.result()
            except Exception as error:  # its worker died again while the result was fetched
                lost = f"its Dask task's result was lost: {type(error).__name__}: {error}"
                book.record_failure(index, lost)
                continue
            book.record(index, result if kind == "batch" else result[0])
    except KeyboardInterrupt:
        interrupted = True
        client.cancel(list(owner))
    results = []
    for book in books:
        code, report = book.finish(interrupted)
        results.append((code, json.loads(report)))
    if interrupted:
        raise KeyboardInterrupt
    return results


def task_threads(client: Client, threads: Optional[int] = None) -> Threads:
    """The fit threads of each task: ``threads`` when given, else per worker its machine's
    cores divided by the task slots of all the workers on that machine (at least 1)."""
    if threads is not None:
        if int(threads) < 1:
            raise InvalidParameterError(f"threads: expected >= 1, got {threads}")
        return int(threads)
    workers = client.scheduler_info(n_workers=-1)["workers"]
    cores = client.run(_cores)
    slots_per_host: dict[str, int] = {}
    for info in workers.values():
        slots_per_host[info["host"]] = slots_per_host.get(info["host"], 0) + info["nthreads"]
    return {
        address: max(1, cores.get(address, 1) // max(1, slots_per_host[info["host"]]))
        for address, info in workers.items()
    }


def _cores() -> int:
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _describe(client: Client, slots: Threads) -> str:
    workers = client.scheduler_info(n_workers=-1)["workers"]
    counts = [slots] if isinstance(slots, int) else sorted(set(slots.values())) or [1]
    plural = "s" if counts[-1] > 1 else ""
    each = f"{'/'.join(map(str, counts))} fit thread{plural} per task"
    address = client.scheduler_info(n_workers=0).get("address", "?")
    return f"{len(workers)} Dask workers at {address} ({each})"


def _failure(future: Future) -> str:
    error = future.exception()
    if isinstance(error, KilledWorker):
        return (
            "its Dask worker died every time it ran it (out of memory or killed); "
            f"not retried further ({error})"
        )
    if future.status == "cancelled":
        return "its Dask task was cancelled"
    return f"its Dask task failed: {type(error).__name__}: {error}"


def _request(
    command: str,
    template: PathLike,
    scans: Union[PathLike, Sequence[PathLike]],
    out_dir: PathLike,
    *,
    resume: bool,
    preset: str,
    recursive: bool,
    glob: Optional[str],
    format: str,
    ascii: bool,
    gt_dir: Optional[PathLike],
    params: dict[str, Any],
) -> dict[str, Any]:
    """The run as the Rust ``RunBook`` takes it; paths absolute, so that workers on other
    machines (on shared storage) find them."""
    request: dict[str, Any] = {
        "command": command,
        "template": os.path.abspath(template),
        "output": os.path.abspath(out_dir),
        "resume": bool(resume),
        "recursive": bool(recursive),
        "glob": glob,
        "format": format,
        "ascii": bool(ascii),
        "gt_dir": None if gt_dir is None else os.path.abspath(gt_dir),
        "preset": preset,
        "params": {k: _plain(v) for k, v in _settings(params).items() if v is not None},
    }
    nested = params.get("params")
    if isinstance(nested, FitParams):
        request["preset"] = nested.preset_name
    if isinstance(scans, (str, os.PathLike)):
        request["input_dir"] = os.path.abspath(scans)
    else:
        request["files"] = [os.path.abspath(p) for p in scans]
    return request


def _settings(given: dict[str, Any]) -> dict[str, Any]:
    """The settings by name: ``params=`` (a :class:`~foldmatch_rs.FitParams` or a dict, as
    :func:`foldmatch_rs.fit` takes it) with the other keywords over it."""
    given = dict(given)
    nested = given.pop("params", None)
    return {**(dict(nested) if nested is not None else {}), **given}


def _book(request: dict[str, Any], progress: bool) -> _core.RunBook:
    """The Rust ``RunBook`` of a request from :func:`_request`, with progress lines or quiet."""
    return _core.RunBook(json.dumps(request), "normal" if progress else "quiet")


def _plain(value: Any) -> Any:
    """NumPy scalars as Python numbers (for JSON)."""
    return value.item() if hasattr(value, "item") and not isinstance(value, (list, dict)) else value


__all__ = [
    "DEFAULT_RETRIES",
    "connect",
    "fit_batch",
    "run_books",
    "task_threads",
    "track_sequences",
]
