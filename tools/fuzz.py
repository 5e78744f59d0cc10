"""Fuzz the mesh readers and the `musclewrap run` command with mutated real inputs.

Every case runs in a child process (a reader of a compiled library may crash outright) with a
time limit, and is classed as:

- ``ok``: read (or the run finished);
- ``refused``: a clear error naming the file (the CLI's exit status 2, or one of musclewrap's
  error types from the reader);
- ``unnamed``: refused, but the message does not name the file;
- ``crash``: any other exception, a traceback, or the process dying;
- ``hang``: over the time limit.

    python tools/fuzz.py --cases 400 --seed 1 [--data ../shared/data]

Prints one line per outcome class and format, and the crashes and hangs in full.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import random
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = r"""
import json, signal, sys, traceback, warnings
warnings.simplefilter("ignore")
LIMIT = int(sys.argv[1])
from musclewrap.mesh import MeshError, read_mesh, clean_mesh
from musclewrap.conditions import LineError
for line in sys.stdin:
    case = json.loads(line)
    print(json.dumps({"start": case["id"]}), flush=True)
    signal.alarm(LIMIT)  # the default action ends the process: a hang
    try:
        if case["kind"] == "mesh":
            V, F = read_mesh(case["path"])
            try:
                clean_mesh(V, F, source=case["path"], repair=True)
                out = "ok"
            except (MeshError, ValueError) as exc:
                out = "refused" if case["path"] in str(exc) or "mesh" in str(exc) else "crash"
        else:
            from musclewrap.cli import main
            import contextlib, io
            err = io.StringIO()
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                rc = main(case["argv"])
            out = {0: "ok", 2: "refused", 3: "ok"}.get(rc, "crash")
            if out == "refused" and "error" not in err.getvalue():
                out = "crash"
        print(json.dumps({"id": case["id"], "outcome": out}), flush=True)
    except (MeshError, LineError, ValueError) as exc:
        named = case.get("path", "") in str(exc)
        print(json.dumps({"id": case["id"], "outcome": "refused" if named else "unnamed",
                          "message": str(exc)[:300]}), flush=True)
    except BaseException:
        print(json.dumps({"id": case["id"], "outcome": "crash",
                          "message": traceback.format_exc()[-1500:]}), flush=True)
"""


def mutate(data: bytes, rng: random.Random) -> bytes:
    """One random damage of a file: truncate, flip, insert, delete, repeat or poison numbers."""
    if not data:
        return data
    kind = rng.choice(["truncate", "flip", "insert", "delete", "repeat", "numbers", "empty"])
    b = bytearray(data)
    if kind == "truncate":
        return bytes(b[: rng.randrange(len(b))])
    if kind == "flip":
        for _ in range(rng.randint(1, 20)):
            i = rng.randrange(len(b))
            b[i] ^= 1 << rng.randrange(8)
        return bytes(b)
    if kind == "insert":
        i = rng.randrange(len(b))
        return bytes(b[:i] + bytes(rng.randrange(256) for _ in range(rng.randint(1, 64))) + b[i:])
    if kind == "delete":
        i = rng.randrange(len(b))
        return bytes(b[:i] + b[i + rng.randint(1, 256) :])
    if kind == "repeat":
        i = rng.randrange(len(b))
        j = min(len(b), i + rng.randint(1, 4096))
        return bytes(b[:j] + b[i:j] + b[j:])
    if kind == "numbers":
        text = data.decode("latin-1")
        tokens = text.split(" ")
        for _ in range(rng.randint(1, 10)):
            k = rng.randrange(len(tokens))
            tokens[k] = rng.choice(["nan", "inf", "-inf", "1e308", "-0", "", "x", "999999999"])
        return " ".join(tokens).encode("latin-1")
    return b""


def seeds(data: Path, work: Path) -> dict[str, list[Path]]:
    """Real files of every format, and a small scene (mesh, line CSV, TOML) to run."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))
    from musclewrap.mesh import read_mesh, write_mesh
    from musclewrap.synthetic import demo_scene

    out: dict[str, list[Path]] = collections.defaultdict(list)
    out["vtk"].append(data / "lhdl" / "muscles" / "LHDL_R_Psoas.vtk")
    out["stl"].append(data / "vhf" / "VHF_Right_Muscle_AdductorLongus_smooth.stl")
    ply = sorted((data / "lhdl" / "muscles_ply").glob("*.ply"))
    out["ply"] += ply[:1]
    V, F = read_mesh(data / "lhdl" / "muscles" / "LHDL_R_Psoas.vtk")
    for ext in ("obj", "off", "vtp"):
        p = work / f"seed.{ext}"
        write_mesh(p, V, F)
        out[ext].append(p)
    # a scene of the synthetic demo, driven by a line CSV
    sc = demo_scene(6)
    write_mesh(work / "muscle.vtp", sc.V, sc.F)
    bV, bF = sc.bones["thigh"]
    write_mesh(work / "thigh.vtp", bV, bF)
    rows = ["frame,time,muscle,line,point,x,y,z"]
    for k in range(6):
        for i, p in enumerate(sc.line(k)["main"]):
            x, y, z = (float(c) for c in p)
            rows.append(f"{k},{k * 0.1},fusiform,main,{i},{x!r},{y!r},{z!r}")
    (work / "lines.csv").write_text("\n".join(rows) + "\n")
    (work / "scene.toml").write_text(
        'name = "fuzz"\n[lines]\ncsv = "lines.csv"\nrest_frame = 0\n'
        '[muscles.fusiform]\nmesh = "muscle.vtp"\nreference = "thigh"\ncage_size = 120\n'
        '[bones.thigh]\nmesh = "thigh.vtp"\n[output]\npaper_frames = 1\ngif = false\n'
    )
    out["scene-toml"].append(work / "scene.toml")
    out["scene-csv"].append(work / "lines.csv")
    out["scene-mesh"].append(work / "muscle.vtp")
    return out


def main() -> None:
    """Make the cases, run them, print the outcome table and every bad case."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=400)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[2] / "shared" / "data"))
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--keep", help="copy the inputs of bad cases into this folder")
    a = ap.parse_args()
    rng = random.Random(a.seed)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        src = seeds(Path(a.data), work)
        kinds = sorted(src)
        # the undamaged inputs must pass, or every damaged one would be refused for nothing
        seed_cases = [
            {
                "id": -1,
                "kind": "run",
                "argv": [
                    "run",
                    str(work / "scene.toml"),
                    "-o",
                    str(work / "seed_out"),
                    "--no-cache",
                ],
            }
        ]
        seed_cases += [
            {"id": -2 - i, "kind": "mesh", "path": str(f)}
            for i, f in enumerate(src[k][0] for k in kinds if not k.startswith("scene-"))
        ]
        bad_seeds = [r for r in run_cases(seed_cases, a.timeout).values() if r["outcome"] != "ok"]
        if bad_seeds:
            raise SystemExit(f"an undamaged input failed: {bad_seeds}")
        cases = []
        for i in range(a.cases):
            fmt = kinds[i % len(kinds)]
            seed_file = rng.choice(src[fmt])
            data = mutate(seed_file.read_bytes(), rng)
            if fmt.startswith("scene-"):
                case_dir = work / f"case{i}"
                case_dir.mkdir()
                for name in ("scene.toml", "lines.csv", "muscle.vtp", "thigh.vtp"):
                    (case_dir / name).write_bytes((work / name).read_bytes())
                (case_dir / seed_file.name).write_bytes(data)
                argv = ["run", str(case_dir / "scene.toml"), "-o", str(case_dir / "out")]
                cases.append({"id": i, "fmt": fmt, "kind": "run", "argv": [*argv, "--no-cache"]})
            else:
                p = work / f"case{i}{seed_file.suffix}"
                p.write_bytes(data)
                cases.append({"id": i, "fmt": fmt, "kind": "mesh", "path": str(p)})
        results = run_cases(cases, a.timeout)
        if a.keep:
            keep = Path(a.keep)
            keep.mkdir(parents=True, exist_ok=True)
            for c in cases:
                if results[c["id"]]["outcome"] in ("unnamed", "crash", "hang"):
                    src_path = Path(c["path"]) if c["kind"] == "mesh" else Path(c["argv"][1]).parent
                    dest = keep / src_path.name
                    if src_path.is_dir():
                        import shutil

                        shutil.copytree(src_path, dest, dirs_exist_ok=True)
                    else:
                        dest.write_bytes(src_path.read_bytes())
    table = collections.Counter((c["fmt"], results[c["id"]]["outcome"]) for c in cases)
    print(f"{len(cases)} cases (seed {a.seed})")
    for fmt in kinds:
        counts = {o: table[(fmt, o)] for o in ("ok", "refused", "unnamed", "crash", "hang")}
        print(f"  {fmt:12s} " + "  ".join(f"{o} {n}" for o, n in counts.items()))
    bad = [c for c in cases if results[c["id"]]["outcome"] in ("unnamed", "crash", "hang")]
    for c in bad:
        r = results[c["id"]]
        print(f"--- case {c['id']} ({c['fmt']}): {r['outcome']}\n{r.get('message', '')}")
    sys.exit(1 if bad else 0)


def run_cases(cases: list[dict], timeout: float) -> dict[int, dict]:
    """Feed the cases to child processes; a child that dies or stalls marks its case."""
    results: dict[int, dict] = {}
    todo = list(cases)
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    while todo:
        child = subprocess.Popen(
            [sys.executable, "-c", CHILD, str(int(timeout))],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
            env=env,
        )
        try:
            out, _ = child.communicate(
                "".join(json.dumps(c) + "\n" for c in todo), timeout=timeout * len(todo)
            )
        except subprocess.TimeoutExpired:
            child.kill()
            out, _ = child.communicate()
        started = None
        for line in out.splitlines():
            msg = json.loads(line)
            if "start" in msg:
                started = msg["start"]
            else:
                results[msg["id"]] = msg
                started = None
        if started is not None:  # the child died or stalled on this case
            code = child.returncode
            results[started] = {
                "id": started,
                "outcome": "hang" if code in (-9, -14, None) else "crash",
                "message": f"child process ended with status {code}",
            }
        todo = [c for c in todo if c["id"] not in results]
    return results


if __name__ == "__main__":
    main()
