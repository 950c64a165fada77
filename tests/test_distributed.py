"""The Dask path (issue #29): ``foldmatch_rs.distributed`` on a real ``LocalCluster`` of worker
processes, against the local ``foldmatch batch`` / ``foldmatch sequence`` on the same files.

One cluster of two single-slot worker processes serves the module (it starts in a few
seconds); the scans are small generated sheets so that every test takes seconds.
"""

from __future__ import annotations

import json
import os
import pathlib
import signal
import subprocess
import sys
import threading
import time

import foldmatch_rs as fm
import pytest
from test_cli import ENV, dressed_scan, write_labelled_ply, write_ply

distributed = pytest.importorskip("distributed")
fmd = pytest.importorskip("foldmatch_rs.distributed")

ITERATIONS = "12"


def local(*args: str, cwd: pathlib.Path) -> subprocess.CompletedProcess:
    """The local command line (no Dask), from the same extension."""
    return subprocess.run(
        [sys.executable, "-m", "foldmatch_rs", *args],
        check=False,
        cwd=cwd,
        env=ENV,
        capture_output=True,
        text=True,
        timeout=120,
    )


def scan_folder(root: pathlib.Path, name: str, count: int, points: int = 300) -> pathlib.Path:
    """``count`` folded sheets of different folds, as scans (the frames of a sequence when the
    folds change smoothly)."""
    folder = root / name
    folder.mkdir()
    for k in range(count):
        case = fm.folded_sheet(nx=12, ny=12, scan_points=points, seed=k + 1, fold_amplitude=0.04 + 0.005 * k)
        write_ply(folder / f"frame{k}.ply", case["scan"])
    return folder


@pytest.fixture(scope="module")
def client():
    with fmd.connect(None, workers=2) as c:
        c.wait_for_workers(2)
        yield c


@pytest.fixture
def data(tmp_path):
    case = fm.folded_sheet(nx=12, ny=12)
    write_ply(tmp_path / "template.ply", case["template_vertices"], case["faces"])
    return tmp_path


def outputs(folder: pathlib.Path) -> dict[str, bytes]:
    """Every fitted mesh of a folder, by relative path (the report and hidden files aside)."""
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*.ply"))
        if not p.name.startswith(".")
    }


def statuses(report: dict) -> dict[str, str]:
    return {f["name"]: f["status"] for f in report["files"]}


def test_the_workers_are_processes(client):
    pids = client.run(os.getpid)
    assert len(pids) == 2
    assert len(set(pids.values())) == 2 and os.getpid() not in pids.values()


def test_fit_batch_equals_the_local_batch_bit_for_bit(client, data):
    scans = scan_folder(data, "scans", 6)
    out = local("batch", "template.ply", "scans", "-o", "local", "--iterations", ITERATIONS, cwd=data)
    assert out.returncode == 0, out.stderr
    report = fmd.fit_batch(
        data / "template.ply", scans, data / "dask", client=client, iterations=int(ITERATIONS)
    )
    assert report == json.loads((data / "dask" / "report.json").read_text())
    expected = outputs(data / "local")
    assert len(expected) == 6
    assert outputs(data / "dask") == expected
    # Every staged output was committed by the driver (renamed once the report recorded it).
    assert not list((data / "dask").glob(".*.staged.*"))
    local_report = json.loads((data / "local" / "report.json").read_text())
    assert report.keys() == local_report.keys()
    assert report["state"] == "complete" and report["command"] == "batch"
    assert (
        report["summary"]
        == local_report["summary"]
        == {
            "total": 6,
            "ok": 6,
            "error": 0,
            "skipped": 0,
            "interrupted": 0,
            "pending": 0,
        }
    )
    assert report["params"] == local_report["params"]
    for mine, theirs in zip(report["files"], local_report["files"]):
        assert mine.keys() == theirs.keys()
        assert (mine["name"], mine["iterations"]) == (theirs["name"], theirs["iterations"])
        assert mine["metrics"] == theirs["metrics"]
    # A list of files: named from the folder that holds them, the same outputs.
    listed = fmd.fit_batch(
        data / "template.ply",
        [scans / "frame3.ply", scans / "frame1.ply"],
        data / "listed",
        client=client,
        iterations=int(ITERATIONS),
    )
    assert [f["name"] for f in listed["files"]] == ["frame3.ply", "frame1.ply"]
    assert outputs(data / "listed") == {k: expected[k] for k in ("frame1.ply", "frame3.ply")}


def test_a_corrupt_scan_is_reported_and_the_others_go_on(client, data):
    scans = scan_folder(data, "scans", 3)
    good = (scans / "frame0.ply").read_bytes()
    (scans / "truncated.ply").write_bytes(good[: len(good) // 3])
    (scans / "empty.obj").write_bytes(b"")
    report = fmd.fit_batch(data / "template.ply", scans, data / "out", client=client, iterations=3)
    assert statuses(report) == {
        "empty.obj": "error",
        "frame0.ply": "ok",
        "frame1.ply": "ok",
        "frame2.ply": "ok",
        "truncated.ply": "error",
    }
    for entry in report["files"]:
        if entry["status"] == "error":
            assert entry["name"] in entry["error"], entry
            assert not pathlib.Path(entry["output"]).exists()
    assert report["summary"]["error"] == 2
    # The console script on the same cluster: exit status 2 (partial failure), as locally.
    address = client.scheduler_info(n_workers=0)["address"]
    out = local(
        "-q", "batch", "template.ply", "scans", "-o", "cli", "--iterations", "3",
        "--scheduler", address, cwd=data,
    )  # fmt: skip
    assert out.returncode == 2, out.stderr
    assert "truncated.ply" in out.stderr
    cli_report = json.loads((data / "cli" / "report.json").read_text())
    assert statuses(cli_report) == statuses(report)
    assert outputs(data / "cli") == outputs(data / "out")


def test_resume_redoes_nothing(client, data):
    scans = scan_folder(data, "scans", 4)
    out_dir = data / "out"
    first = fmd.fit_batch(data / "template.ply", scans, out_dir, client=client, iterations=5)
    assert set(statuses(first).values()) == {"ok"}
    before = {p: p.stat().st_mtime_ns for p in out_dir.glob("*.ply")}
    again = fmd.fit_batch(data / "template.ply", scans, out_dir, client=client, resume=True, iterations=5)
    assert set(statuses(again).values()) == {"skipped"}
    assert {p: p.stat().st_mtime_ns for p in out_dir.glob("*.ply")} == before
    assert [f["metrics"] for f in again["files"]] == [f["metrics"] for f in first["files"]]
    # One output lost: only that scan is fitted again, to the same bytes.
    lost = out_dir / "frame2.ply"
    kept = lost.read_bytes()
    lost.unlink()
    third = fmd.fit_batch(data / "template.ply", scans, out_dir, client=client, resume=True, iterations=5)
    assert statuses(third) == {
        "frame0.ply": "skipped",
        "frame1.ply": "skipped",
        "frame2.ply": "ok",
        "frame3.ply": "skipped",
    }
    assert lost.read_bytes() == kept
    assert {p: p.stat().st_mtime_ns for p in out_dir.glob("*.ply") if p != lost} == {
        p: t for p, t in before.items() if p != lost
    }


def test_two_sequences_tracked_in_parallel_equal_their_local_runs(client, data):
    walk = scan_folder(data, "walk", 4)
    jump = scan_folder(data, "jump", 4, points=350)
    # A corrupt frame: recorded, and the next frame starts from the last good fit (frame1).
    (jump / "frame1b.ply").write_bytes(b"ply\nformat ascii 1.0\n")
    for name, status in (("walk", 0), ("jump", 2)):
        out = local(
            "sequence", "template.ply", name, "-o", f"local/{name}", "--iterations", ITERATIONS,
            cwd=data,
        )  # fmt: skip
        assert out.returncode == status, out.stderr
    with distributed.get_task_stream(client) as stream:
        reports = fmd.track_sequences(
            data / "template.ply",
            [walk, jump],
            data / "dask",
            client=client,
            iterations=int(ITERATIONS),
        )
    assert outputs(data / "dask") == outputs(data / "local")
    assert len(outputs(data / "local")) == 8
    warm = {
        "walk": [None, "frame0.ply", "frame1.ply", "frame2.ply"],
        "jump": [None, "frame0.ply", "frame1.ply", "frame1.ply", "frame2.ply"],
    }
    for name in ("walk", "jump"):
        mine = reports[name]
        theirs = json.loads((data / "local" / name / "report.json").read_text())
        assert mine["command"] == "sequence" and mine["summary"]["ok"] == 4
        assert [f.get("warm_start") for f in mine["files"]] == warm[name]
        assert [f.get("warm_start") for f in theirs["files"]] == warm[name]
        assert statuses(mine) == statuses(theirs)
        assert mine["params"] == theirs["params"]
    assert statuses(reports["jump"])["frame1b.ply"] == "error"
    # The two chains ran on both workers.
    workers = {t["worker"] for t in stream.data if t["key"].startswith("foldmatch-sequence")}
    assert len(workers) == 2


def test_sequence_resume_warm_starts_from_the_kept_frames(client, data):
    frames = scan_folder(data, "walk", 4)
    full = fmd.track_sequences(
        data / "template.ply", [frames], data / "out", client=client, iterations=int(ITERATIONS)
    )
    expected = outputs(data / "out")
    (data / "out" / "walk" / "frame3.ply").unlink()
    again = fmd.track_sequences(
        data / "template.ply",
        [frames],
        data / "out",
        client=client,
        resume=True,
        iterations=int(ITERATIONS),
    )
    assert statuses(again["walk"]) == {
        "frame0.ply": "skipped",
        "frame1.ply": "skipped",
        "frame2.ply": "skipped",
        "frame3.ply": "ok",
    }
    assert again["walk"]["files"][3]["warm_start"] == "frame2.ply"
    assert outputs(data / "out") == expected
    assert full["walk"]["summary"]["ok"] == 4


def test_the_console_script_runs_on_a_scheduler(client, data):
    scan_folder(data, "frames", 3)
    address = client.scheduler_info(n_workers=0)["address"]
    for command in ("batch", "sequence"):
        here = local(command, "template.ply", "frames", "-o", f"local-{command}", cwd=data)
        assert here.returncode == 0, here.stderr
        there = local(
            command, "template.ply", "frames", "-o", f"dask-{command}", "--scheduler", address,
            cwd=data,
        )  # fmt: skip
        assert there.returncode == 0, there.stderr
        assert f"{command}: 3 ok, 0 failed, 0 skipped" in there.stderr
        assert "[3/3] ok" in there.stderr
        assert outputs(data / f"dask-{command}") == outputs(data / f"local-{command}")


def test_the_scan_weights_property_reaches_the_workers(client, data):
    """``--scan-weights-property`` on a scheduler: the same outputs as the local batch and the
    same ``scan_weights`` entries."""
    folder = data / "labelled"
    folder.mkdir()
    for k in range(2):
        case = fm.folded_sheet(nx=12, ny=12, scan_points=300, seed=k + 1)
        points, mask = dressed_scan(case["scan"])
        write_labelled_ply(folder / f"scan{k}.ply", points, mask, "label")
    args = ("batch", "template.ply", "labelled", "--iterations", ITERATIONS)
    weights = ("--scan-weights-property", "label")
    here = local(*args, "-o", "local", *weights, cwd=data)
    assert here.returncode == 0, here.stderr
    address = client.scheduler_info(n_workers=0)["address"]
    there = local(*args, "-o", "dask", *weights, "--scheduler", address, cwd=data)
    assert there.returncode == 0, there.stderr
    assert outputs(data / "dask") == outputs(data / "local")
    unweighted = local(*args, "-o", "plain", cwd=data)
    assert unweighted.returncode == 0, unweighted.stderr
    assert outputs(data / "plain") != outputs(data / "local")
    report = json.loads((data / "dask" / "report.json").read_text())
    for entry in report["files"]:
        assert entry["scan_weights"] == {
            "source": "property",
            "property": "label",
            "points": 400,
            "zero_weight": 100,
        }


def test_task_threads_share_the_cores(client):
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    slots = fmd.task_threads(client)
    assert set(slots) == set(client.scheduler_info(n_workers=-1)["workers"])
    assert set(slots.values()) == {max(1, cores // 2)}
    assert fmd.task_threads(client, 3) == 3
    with pytest.raises(fm.InvalidParameterError):
        fmd.task_threads(client, 0)


def test_setup_errors_are_raised_before_any_task(client, data):
    with pytest.raises(fm.RunSetupError, match="no .ply or .obj files"):
        (data / "nothing").mkdir()
        fmd.fit_batch(data / "template.ply", data / "nothing", data / "out", client=client)
    with pytest.raises(fm.RunSetupError, match="damping"):
        fmd.fit_batch(data / "template.ply", [data / "template.ply"], data / "o", client=client, damping=5)
    with pytest.raises(fm.RunSetupError, match="missing.ply"):
        fmd.fit_batch(data / "missing.ply", data, data / "out", client=client)


def test_a_worker_killed_mid_run_loses_nothing(client, data):
    scans = scan_folder(data, "scans", 8, points=2000)
    args = ("--iterations", "40")
    out = local("batch", "template.ply", "scans", "-o", "local", *args, cwd=data)
    assert out.returncode == 0, out.stderr
    result: dict = {}

    def run() -> None:
        result["report"] = fmd.fit_batch(
            data / "template.ply", scans, data / "dask", client=client, iterations=40
        )

    worker = threading.Thread(target=run)
    worker.start()
    killed = None
    deadline = time.monotonic() + 60
    while killed is None and time.monotonic() < deadline and worker.is_alive():
        busy = [
            address
            for address, keys in client.processing().items()
            if any(str(k).startswith("foldmatch-batch") for k in keys)
        ]
        if busy and any((data / "dask").glob("*.ply")):
            pid = client.run(os.getpid, workers=[busy[0]])[busy[0]]
            os.kill(pid, signal.SIGKILL)
            killed = (busy[0], pid, len(list((data / "dask").glob("*.ply"))))
        else:
            time.sleep(0.02)
    worker.join(120)
    assert killed is not None, "no worker was busy to kill"
    assert killed[2] < 8, "the batch had finished before the kill"
    report = result["report"]
    assert set(statuses(report).values()) == {"ok"}, report["files"]
    assert outputs(data / "dask") == outputs(data / "local")
    assert not list((data / "dask").glob(".*.staged.*"))
    client.wait_for_workers(2, timeout=60)
    assert killed[1] not in client.run(os.getpid).values()


def test_ctrl_c_cancels_and_writes_an_interrupted_report(client, data):
    # Enough work that the batch cannot drain between the first finished scan and the signal,
    # even on a loaded machine (12 scans did, once, in the full suite).
    scan_folder(data, "scans", 40, points=3000)
    address = client.scheduler_info(n_workers=0)["address"]
    argv = [sys.executable, "-m", "foldmatch_rs", "-q", "batch", "template.ply", "scans", "-o", "out"]
    run = subprocess.Popen(
        [*argv, "--scheduler", address],
        cwd=data,
        env=ENV,
        stderr=subprocess.PIPE,
        text=True,
    )
    report_path = data / "out" / "report.json"
    deadline = time.monotonic() + 60
    while run.poll() is None and time.monotonic() < deadline:
        if report_path.exists() and '"status": "ok"' in report_path.read_text():
            run.send_signal(signal.SIGINT)
            break
        time.sleep(0.02)
    _, stderr = run.communicate(timeout=60)
    assert run.returncode == 130, stderr
    report = json.loads(report_path.read_text())
    assert report["state"] == "interrupted"
    summary = report["summary"]
    assert summary["error"] == 0 and summary["ok"] >= 1
    assert summary["pending"] + summary["interrupted"] >= 1
    for entry in report["files"]:
        if entry["status"] == "ok":
            assert pathlib.Path(entry["output"]).exists(), entry
    # Tasks already running finish on their workers; --resume then fits only what is left.
    again = local(
        "-q", "batch", "template.ply", "scans", "-o", "out", "--resume", "--scheduler", address, cwd=data
    )
    assert again.returncode == 0, again.stderr
    resumed = json.loads(report_path.read_text())
    assert resumed["summary"]["skipped"] == summary["ok"]
    assert resumed["summary"]["ok"] == 40 - summary["ok"]


def test_importing_the_package_does_not_import_dask():
    code = (
        "import sys, foldmatch_rs, foldmatch_rs.__main__; "
        "assert not {'dask', 'distributed'} & set(sys.modules), sorted(sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr


def test_without_dask_scheduler_says_what_to_install(data):
    scan_folder(data, "scans", 1)
    code = (
        "import sys; sys.modules['dask'] = sys.modules['distributed'] = None; "
        "from foldmatch_rs.__main__ import main; "
        "sys.argv = ['foldmatch', 'batch', 'template.ply', 'scans', '-o', 'out', '--scheduler', 'local']; "
        "main()"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=data)
    assert out.returncode == 1
    assert "pip install 'dask[distributed]" in out.stderr
    assert not (data / "out").exists()


FORKED_WORKERS = """
import dask, sys, numpy as np
import foldmatch_rs as fm
from foldmatch_rs import distributed as fmd

def fit_in_worker(case):
    # The global-pool path of the bindings, in a worker forked from a parent whose rayon pool
    # is running: without the fork guard this waits forever on the parent's threads.
    r = fm.fit(case["template_vertices"], case["faces"], case["scan"], iterations=5)
    return r.vertices

if __name__ == "__main__":
    case = fm.folded_sheet(nx=10, ny=10, scan_points=200)
    here = fm.fit(case["template_vertices"], case["faces"], case["scan"], iterations=5)
    with dask.config.set({"distributed.worker.multiprocessing-method": "fork"}):
        with fmd.connect(None, workers=1) as client:
            there = client.submit(fit_in_worker, case).result(timeout=60)
    assert np.array_equal(here.vertices, there)
    print("ok")
"""


def test_the_fork_guard_holds_in_forked_workers(tmp_path):
    script = tmp_path / "forked.py"
    script.write_text(FORKED_WORKERS)
    out = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=120, cwd=tmp_path
    )
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.strip() == "ok"
