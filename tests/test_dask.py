"""Batches on a Dask cluster started here (loopback): the same files as the local run,
also with a worker killed mid-run."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv

from musclewrap.cli import main
from test_run import _gif_frames, _twin_scene

distributed = pytest.importorskip("distributed") if not os.environ.get("CI") else None
if distributed is None:
    import distributed  # noqa: F811  # required in CI: the [dev] extra has it

pytestmark = pytest.mark.slow


def _start(args: list[str], log: Path) -> subprocess.Popen:
    with open(log, "w") as fh:  # the child keeps its own copy of the handle
        return subprocess.Popen(
            [sys.executable, "-m", "dask", *args],
            stdout=fh,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )


@pytest.fixture
def cluster(tmp_path):
    """``dask scheduler`` and two ``dask worker`` processes on this machine."""
    sched = tmp_path / "scheduler.json"
    procs = [
        _start(
            ["scheduler", "--scheduler-file", str(sched), "--host", "127.0.0.1", "--port", "0",
             "--dashboard-address", ":0"],
            tmp_path / "scheduler.log",
        )
    ]  # fmt: skip
    deadline = time.time() + 60
    while not sched.is_file() and time.time() < deadline:
        time.sleep(0.1)
    address = json.loads(sched.read_text())["address"]
    for i in range(2):
        procs.append(
            _start(
                ["worker", "--scheduler-file", str(sched), "--nthreads", "1", "--no-nanny",
                 "--name", f"w{i}", "--host", "127.0.0.1"],
                tmp_path / f"worker{i}.log",
            )
        )  # fmt: skip
    client = distributed.Client(address, timeout="30s")
    client.wait_for_workers(2, timeout=60)
    client.close()
    yield address, procs[1:]
    for p in procs:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
        p.wait()


def _batch(tmp_path: Path, n_frames: int) -> list[Path]:
    scenes = []
    for name in ("subject_a", "subject_b"):
        d = tmp_path / name
        d.mkdir()
        _, toml = _twin_scene(d, n_frames=n_frames)
        scenes.append(toml.rename(d / f"{name}.toml"))
    # the second subject moves differently: every line point shifted
    lines = tmp_path / "subject_b" / "lines.csv"
    with lines.open() as fh:
        rows = list(csv.reader(fh))
    with lines.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(rows[0])
        for r in rows[1:]:
            w.writerow([*r[:5], float(r[5]) + 0.5, *r[6:]])
    return scenes


def _same_outputs(a: Path, b: Path) -> None:
    """The same files; meshes within 1e-9 of their size; report rows equal but timings."""
    files = sorted(p.relative_to(a) for p in a.rglob("*.vtp"))
    assert files and files == sorted(p.relative_to(b) for p in b.rglob("*.vtp"))
    for f in files:
        ma, mb = pv.read(a / f), pv.read(b / f)
        Va, Vb = np.asarray(ma.points), np.asarray(mb.points)
        size = max(np.ptp(Va, axis=0).max(), 1.0)
        assert Va.shape == Vb.shape and np.abs(Va - Vb).max() <= 1e-9 * size, f
        assert np.array_equal(ma.faces, mb.faces) and np.array_equal(ma.lines, mb.lines), f
    with (a / "report.csv").open() as fa, (b / "report.csv").open() as fb:
        ra, rb = list(csv.DictReader(fa)), list(csv.DictReader(fb))
    assert len(ra) == len(rb)
    for x, y in zip(ra, rb, strict=True):
        x.pop("seconds"), y.pop("seconds")
        assert x == y
    assert (a / "scene.pvd").read_text() == (b / "scene.pvd").read_text()
    # the pictures, where drawn (off-screen OpenGL here): the same, picture by picture
    assert (a / "scene.gif").is_file() == (b / "scene.gif").is_file()
    if (a / "scene.gif").is_file():
        from PIL import ImageChops

        ga, gb = _gif_frames(a / "scene.gif"), _gif_frames(b / "scene.gif")
        assert len(ga) == len(gb)
        for x, y in zip(ga, gb, strict=True):
            assert ImageChops.difference(x, y).getbbox() is None


def test_batch_on_a_dask_cluster_gives_the_local_files(tmp_path, cluster):
    address, _ = cluster
    scenes = _batch(tmp_path, n_frames=40)
    for toml in scenes:  # the pictures too: tasks on the workers, pictures back to the client
        toml.write_text(toml.read_text().replace("gif = false\n", "gif = true\ngif_every = 8\n"))
    common = ["run", *map(str, scenes), "--cache-dir", str(tmp_path / "cache")]
    assert main([*common, "-o", str(tmp_path / "local"), "--workers", "1"]) == 0
    assert main([*common, "-o", str(tmp_path / "dask"), "--scheduler", address]) == 0
    for s in ("subject_a", "subject_b"):
        _same_outputs(tmp_path / "local" / s, tmp_path / "dask" / s)
        assert not (tmp_path / "dask" / s / ".musclewrap-run").exists()
    # the two subjects' frames differ (a batch, not one scene twice)
    f = Path("fusiform") / "fusiform_lines_0005.vtp"
    Pa = pv.read(tmp_path / "local" / "subject_a" / f).points
    Pb = pv.read(tmp_path / "local" / "subject_b" / f).points
    assert np.allclose(Pb - Pa, [0.5, 0, 0])


def test_a_worker_killed_mid_batch(tmp_path, cluster):
    """One of the two workers is killed while the batch runs: its tasks run again on the
    other one, and the files are those of the local run."""
    address, workers = cluster
    scenes = _batch(tmp_path, n_frames=240)
    common = ["run", *map(str, scenes), "--no-gif", "--cache-dir", str(tmp_path / "cache")]
    assert main([*common, "-o", str(tmp_path / "local"), "--workers", "1"]) == 0
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    run = subprocess.Popen(
        [sys.executable, "-m", "musclewrap.cli", *common, "-o", str(tmp_path / "dask"),
         "--scheduler", address],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    journal = tmp_path / "dask" / "subject_a" / ".musclewrap-run"
    deadline = time.time() + 300
    while not list(journal.glob("chunk-*.json")) and time.time() < deadline:
        assert run.poll() is None, run.stdout.read()
        time.sleep(0.05)
    os.killpg(workers[0].pid, signal.SIGKILL)
    out, _ = run.communicate(timeout=600)
    assert run.returncode == 0, out
    for s in ("subject_a", "subject_b"):
        _same_outputs(tmp_path / "local" / s, tmp_path / "dask" / s)


def test_an_output_folder_the_workers_cannot_reach_is_refused(tmp_path, cluster, monkeypatch):
    from musclewrap.run import _dask

    address, _ = cluster
    scenes = _batch(tmp_path, n_frames=4)
    # the workers look for the client's token file under another name: as on another machine
    monkeypatch.setattr(
        _dask,
        "_check_paths",
        lambda paths, token: f"{paths[0]}: not reachable from the Dask worker on elsewhere",
    )
    code = main(["run", *map(str, scenes), "--no-gif", "-o", str(tmp_path / "o"),
                 "--scheduler", address])  # fmt: skip
    assert code == 2
    assert not (tmp_path / "o" / "subject_a" / "fusiform").exists()
