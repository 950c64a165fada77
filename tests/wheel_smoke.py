"""Smoke test of a built ``foldmatch_rs`` wheel, as a user without Rust installs it (``make wheel-test``).

    python tests/wheel_smoke.py --platform manylinux_2_17 dist/foldmatch_rs-*.whl

Outside (the development venv's Python): checks the wheel's tags (abi3, the requested manylinux
policy) against ``auditwheel show``, makes a fresh venv, checks that no Rust toolchain is reachable
on the PATH it will use, installs the wheel there with ``pip install --only-binary=:all:`` (its
dependencies come from PyPI as wheels, nothing is compiled) and ``pip check``\\ s it. Inside (that
venv's Python, started by the outside stage with ``--inside``): imports the installed package, fits
a template to a scan made here with NumPy and asserts the fit ends closer to the scan than it
starts, then runs the ``foldmatch`` console script (``--version``, ``fit`` on files written here,
``demo``) and parses what it writes. Exits non-zero with the failed check's message.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
import venv
import zipfile
from pathlib import Path

# Tools whose presence on the fresh venv's PATH would mean the wheel could have been built there.
TOOLCHAIN = ("cargo", "rustc", "rustup", "maturin", "zig")


class SmokeFailure(Exception):
    """A check of the wheel or of the installed package failed; the message names which."""


def check(condition: bool, message: str) -> None:
    if not condition:
        raise SmokeFailure(message)


def wheel_tags(wheel: Path) -> tuple[str, str, set[str]]:
    """(python tag, abi tag, platform tags) from the wheel's file name (PEP 427, PEP 600)."""
    parts = wheel.name[: -len(".whl")].split("-")
    check(len(parts) == 5, f"{wheel.name}: not a wheel file name name-version-python-abi-platform")
    return parts[2], parts[3], set(parts[4].split("."))


def auditwheel_tag(wheel: Path) -> str:
    """The most compatible platform tag ``auditwheel show`` finds for the wheel's shared library."""
    auditwheel = Path(sys.executable).with_name("auditwheel")
    out = subprocess.run([str(auditwheel), "show", str(wheel)], capture_output=True, text=True)
    check(out.returncode == 0, f"auditwheel show {wheel.name} failed:\n{out.stdout}{out.stderr}")
    # auditwheel wraps its prose at ~70 columns; the tag itself is quoted.
    flat = " ".join(out.stdout.split())
    found = re.search(r'consistent with the following platform tag: "([^"]+)"', flat)
    check(found is not None, f"auditwheel show printed no platform tag:\n{out.stdout}")
    return found.group(1)


def check_wheel(wheel: Path, policy: str) -> None:
    python_tag, abi_tag, platforms = wheel_tags(wheel)
    check(abi_tag == "abi3", f"{wheel.name}: ABI tag {abi_tag}, expected abi3 (one wheel per platform)")
    check(python_tag == "cp39", f"{wheel.name}: python tag {python_tag}, expected cp39 (requires-python)")
    expected = f"{policy}_{platform.machine()}"
    check(expected in platforms, f"{wheel.name}: platform tags {sorted(platforms)} lack {expected}")
    audited = auditwheel_tag(wheel)
    check(audited == expected, f"auditwheel finds {wheel.name} needs {audited}, the wheel claims {expected}")
    with zipfile.ZipFile(wheel) as zf:
        names = zf.namelist()
    extensions = [n for n in names if n.endswith(".so")]
    check(extensions == ["foldmatch_rs/_foldmatch_rs.abi3.so"], f"{wheel.name}: extensions {extensions}")
    stray = [n for n in names if not n.startswith(("foldmatch_rs/", "foldmatch_rs-"))]
    check(not stray, f"{wheel.name}: files outside the package and its metadata: {stray}")
    print(f"wheel: {wheel.name}; auditwheel: {audited}")


def clean_env(venv_dir: Path) -> dict[str, str]:
    """The environment of a user with only the fresh venv on PATH: no Rust, no development venv."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("CARGO", "RUSTUP", "PYTHON"))}
    env.pop("VIRTUAL_ENV", None)
    env["PATH"] = str(venv_dir / "bin")
    return env


def install(wheel: Path, venv_dir: Path) -> dict[str, str]:
    start = time.perf_counter()
    venv.EnvBuilder(with_pip=True, clear=True).create(venv_dir)
    env = clean_env(venv_dir)
    for tool in TOOLCHAIN:
        check(shutil.which(tool, path=env["PATH"]) is None, f"{tool} is on the fresh venv's PATH")
    shell = subprocess.run(["/bin/sh", "-c", "command -v cargo"], env=env, capture_output=True)
    check(shell.returncode != 0, f"`command -v cargo` found {shell.stdout!r} with the fresh venv's PATH")
    python = str(venv_dir / "bin" / "python")
    pip = [python, "-m", "pip", "--disable-pip-version-check", "--no-input"]
    # --only-binary: the wheel and its dependencies install as they are; a source build would
    # need a compiler and is refused.
    for step in (["install", "-q", "--only-binary=:all:", str(wheel)], ["check"]):
        done = subprocess.run(pip + step, env=env, capture_output=True, text=True)
        check(done.returncode == 0, f"pip {' '.join(step)} failed:\n{done.stdout}{done.stderr}")
    print(f"installed into a fresh venv without Rust on PATH in {time.perf_counter() - start:.1f} s")
    return env


# ---------------------------------------------------------------------------------------------
# Inside the fresh venv: only the wheel and its declared dependencies (NumPy) are importable.


def sheet(n: int):
    """A flat n×n grid on the unit square (z = 0), two triangles per cell."""
    import numpy as np

    u, v = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, n), indexing="xy")
    vertices = np.column_stack([u.ravel(), v.ravel(), np.zeros(n * n)])
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="xy")
    a = (j * n + i).ravel()
    faces = np.concatenate([np.column_stack([a, a + 1, a + n + 1]), np.column_stack([a, a + n + 1, a + n])])
    return vertices, faces.astype(np.int64)


def folded_scan(points: int, seed: int):
    """Points on the unit sheet folded along x (two waves of amplitude 0.06), shifted, with noise."""
    import numpy as np

    rng = np.random.default_rng(seed)
    u, v = rng.random(points), rng.random(points)
    z = 0.06 * np.sin(4.0 * np.pi * u) + 0.03 * v
    scan = np.column_stack([u, v, z]) + np.array([0.05, -0.03, 0.02])
    return scan + rng.normal(scale=0.002, size=scan.shape)


def mean_nearest(a, b) -> float:
    """Mean distance from each point of ``a`` to the nearest point of ``b`` (brute force)."""
    import numpy as np

    best = np.full(len(a), np.inf)
    for start in range(0, len(a), 256):
        block = a[start : start + 256]
        d2 = ((block[:, None, :] - b[None, :, :]) ** 2).sum(axis=2)
        best[start : start + 256] = d2.min(axis=1)
    return float(np.sqrt(best).mean())


def chamfer(vertices, scan) -> float:
    return 0.5 * (mean_nearest(vertices, scan) + mean_nearest(scan, vertices))


def write_obj(path: Path, vertices, faces) -> None:
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in vertices.tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces.tolist()]
    path.write_text("\n".join(lines) + "\n")


def write_ply_points(path: Path, points) -> None:
    header = ["ply", "format ascii 1.0", f"element vertex {len(points)}"]
    header += [f"property double {c}" for c in "xyz"] + ["end_header"]
    path.write_text("\n".join(header + [f"{x!r} {y!r} {z!r}" for x, y, z in points.tolist()]) + "\n")


PLY_TYPES = {"char": "i1", "uchar": "u1", "short": "i2", "ushort": "u2", "int": "i4", "uint": "u4",
             "float": "f4", "double": "f8", "int8": "i1", "uint8": "u1", "int16": "i2",
             "uint16": "u2", "int32": "i4", "uint32": "u4", "float32": "f4", "float64": "f8"}  # fmt: skip


def read_ply_vertices(path: Path):
    """The vertex element of a binary little-endian PLY (what ``foldmatch`` writes) as a record array."""
    import numpy as np

    data = path.read_bytes()
    end = data.find(b"end_header\n")
    check(end > 0, f"{path}: no PLY header")
    header = data[:end].decode("ascii").splitlines()
    check(header[0] == "ply" and header[1].startswith("format binary_little_endian"), f"{path}: {header[:2]}")
    elements = [line.split() for line in header if line.startswith(("element", "property"))]
    check(elements[0][:2] == ["element", "vertex"], f"{path}: the first element is not vertex")
    count, fields = int(elements[0][2]), []
    for words in elements[1:]:
        if words[0] == "element":
            break
        check(words[1] != "list", f"{path}: list property {words[-1]} in the vertex element")
        fields.append((words[2], "<" + PLY_TYPES[words[1]]))
    return np.frombuffer(data, dtype=np.dtype(fields), count=count, offset=end + len("end_header\n"))


def run_cli(args: list[str]) -> subprocess.CompletedProcess:
    done = subprocess.run(args, capture_output=True, text=True)
    check(done.returncode == 0, f"{' '.join(args)} exited {done.returncode}:\n{done.stdout}{done.stderr}")
    return done


def inside(work: Path) -> None:
    from importlib import metadata

    import foldmatch_rs as fm
    import numpy as np

    origin = Path(fm.__file__).resolve()
    check(Path(sys.prefix).resolve() in origin.parents, f"foldmatch_rs imported from {origin}, not the venv")
    version = metadata.version("foldmatch-rs")

    template, faces = sheet(21)
    scan = folded_scan(3000, seed=7)
    start = time.perf_counter()
    result = fm.fit(template, faces, scan)
    seconds = time.perf_counter() - start
    fitted = np.asarray(result.vertices)
    check(fitted.shape == template.shape and np.isfinite(fitted).all(), f"fit vertices {fitted.shape}")
    before, after = chamfer(template, scan), chamfer(fitted, scan)
    check(after < 0.5 * before, f"fm.fit: chamfer to the scan {before:.4f} → {after:.4f}, not halved")
    print(f"fm.fit from the wheel: chamfer {before:.4f} → {after:.4f} in {seconds:.2f} s")

    shown = run_cli(["foldmatch", "--version"]).stdout.strip()
    check(shown == f"foldmatch {version}", f"foldmatch --version printed {shown!r}, the wheel is {version}")
    module = run_cli([sys.executable, "-m", "foldmatch_rs", "--version"]).stdout.strip()
    check(module == shown, f"python -m foldmatch_rs --version printed {module!r}, the script {shown!r}")

    write_obj(work / "template.obj", template, faces)
    write_ply_points(work / "scan.ply", scan)
    run_cli(["foldmatch", "fit", "template.obj", "scan.ply", "-o", "fitted.ply", "--report", "report.json"])
    report = json.loads((work / "report.json").read_text())
    check(report["status"] == "ok" and report["iterations"] > 0, f"foldmatch fit report: {report['status']}")
    cli_vertices = read_ply_vertices(work / "fitted.ply")
    cli_fitted = np.column_stack([cli_vertices[c] for c in "xyz"])
    check(cli_fitted.shape == template.shape, f"foldmatch fit wrote {len(cli_fitted)} vertices")
    cli_after = chamfer(cli_fitted, scan)
    check(cli_after < 0.5 * before, f"foldmatch fit: chamfer {before:.4f} → {cli_after:.4f}, not halved")
    print(f"foldmatch fit from the wheel: chamfer {before:.4f} → {cli_after:.4f}")

    run_cli(["foldmatch", "demo", "-o", "demo"])
    demo = json.loads((work / "demo" / "report.json").read_text())
    check(demo["status"] == "ok", f"foldmatch demo report: {demo['status']}")
    demo_template = read_ply_vertices(work / "demo" / "template.ply")
    demo_fitted = read_ply_vertices(work / "demo" / "fitted.ply")
    check(len(demo_fitted) == len(demo_template) > 0, "foldmatch demo: fitted and template vertex counts")
    check(
        "wvf_magnitude" in (demo_fitted.dtype.names or ()), "foldmatch demo: no wrinkle field in fitted.ply"
    )
    print(f"foldmatch demo from the wheel: {len(demo_fitted)} vertices, report status ok")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("wheels", nargs="*", type=Path, help="the wheel (exactly one)")
    parser.add_argument(
        "--platform", default="manylinux_2_17", help="the manylinux policy `make wheel` built"
    )
    parser.add_argument("--inside", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    try:
        if args.inside is not None:
            inside(args.inside)
            return 0
        check(len(args.wheels) == 1, f"expected one wheel, got {[str(w) for w in args.wheels]}")
        wheel = args.wheels[0].resolve()
        check_wheel(wheel, args.platform)
        with tempfile.TemporaryDirectory(prefix="foldmatch-wheel-") as tmp:
            env = install(wheel, Path(tmp) / "venv")
            work = Path(tmp) / "work"
            work.mkdir()
            python = str(Path(tmp) / "venv" / "bin" / "python")
            done = subprocess.run(
                [python, str(Path(__file__).resolve()), "--inside", str(work)], cwd=work, env=env
            )
            check(done.returncode == 0, "the checks inside the fresh venv failed (above)")
    except SmokeFailure as failure:
        print(f"wheel smoke test FAILED: {failure}", file=sys.stderr)
        return 1
    print("wheel smoke test passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
