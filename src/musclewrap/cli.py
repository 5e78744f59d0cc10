"""Command-line interface: ``musclewrap init | check | run | prepare | deform | demo | bench``."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from ._paths import overwrite_clash
from ._version import __version__

__all__ = ["main"]


def _point(text: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,Z numbers, got {text!r}") from None
    if len(vals) != 3:
        raise argparse.ArgumentTypeError(f"expected three comma-separated numbers, got {text!r}")
    return vals


#: the sub-commands of the parser (argparse's type for them)
_Commands = argparse._SubParsersAction


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="musclewrap",
        description="Deform muscle surface meshes to follow their action lines, keeping volume exactly.",
    )
    p.add_argument("--version", action="version", version=f"musclewrap {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    _add_prepare(sub)
    _add_deform(sub)
    _add_run(sub)
    _add_init(sub)
    _add_check(sub)
    _add_demo(sub)
    _add_view(sub)
    _add_bench(sub)
    return p


def _add_prepare(sub: _Commands) -> None:
    """The ``prepare`` sub-command's arguments."""
    pr = sub.add_parser("prepare", help="build cage, coordinates and Laplacian once per muscle")
    pr.add_argument("mesh", help="closed muscle surface (.stl .obj .ply .off .vtk .vtp)")
    pr.add_argument("-o", "--output", required=True, help="prepared-muscle file (.npz)")
    pr.add_argument("--cage-size", type=int, default=None, help="target number of cage vertices")


def _add_deform(sub: _Commands) -> None:
    """The ``deform`` sub-command's arguments."""
    de = sub.add_parser("deform", help="deform a muscle from its rest to its current action lines")
    de.add_argument("mesh", help="rest-pose muscle surface")
    de.add_argument("--rest", required=True, help="rest action lines, CSV with header line,x,y,z")
    de.add_argument(
        "--current", required=True, help="current action lines, same CSV format and line names"
    )
    de.add_argument(
        "-o", "--output", required=True, help="deformed mesh (.vtp .vtk .stl .ply .obj .off)"
    )
    de.add_argument("--report", help="JSON report path")
    de.add_argument(
        "--prepared", help="prepared-muscle file from 'musclewrap prepare' (skips preparation)"
    )
    de.add_argument("--cage-size", type=int, default=None, help="target number of cage vertices")
    de.add_argument("--reference-rest", type=_point, help="reference point in the rest pose, X,Y,Z")
    de.add_argument(
        "--reference-current", type=_point, help="reference point in the current pose, X,Y,Z"
    )
    de.add_argument(
        "--method", choices=("sqp", "exact", "paper"), default="sqp", help="solver (default sqp)"
    )
    de.add_argument(
        "--bone",
        action="append",
        default=[],
        metavar="MESH",
        help="a bone as it is in the current pose (same frame and units as the lines); the "
        "muscle is kept out of it (repeatable)",
    )
    de.add_argument(
        "--margin", type=float, default=0.0, help="distance kept from every --bone (mesh units)"
    )
    de.add_argument(
        "--allow-unconverged",
        action="store_true",
        help="write the result and exit 0 even if the solve did not converge (a result "
        "without finite positions is never written)",
    )


def _add_run(sub: _Commands) -> None:
    """The ``run`` sub-command's arguments."""
    ru = sub.add_parser(
        "run",
        help="deform every muscle of a scene (OpenSim model + motion) for every frame",
        description=(
            "Read a scene file (TOML; see examples/ and docs/motions.md), compute each muscle's "
            "action lines per frame with OpenSim (or read them from a CSV), deform every "
            "muscle, and write OUTDIR/<muscle>/<muscle>_<frame>.vtp, bones, action lines, "
            "scene.pvd (ParaView), report.csv, volume_error.png, convergence.png, "
            "penetration.png (scenes with bones or several muscles) and scene.gif. Muscles are "
            "kept out of the scene's bones and out of each other unless --no-collisions or "
            "[collisions] enabled = false ([collisions] muscles = false: bones only). Several "
            "scenes run as one batch, into OUTDIR/<scene file stem>/ each."
        ),
    )
    ru.add_argument("scene", nargs="+", help="scene file(s) (.toml)")
    ru.add_argument(
        "-o",
        "--output",
        help="output folder (default for one scene: its name next to it; required for several)",
    )
    ru.add_argument(
        "--scheduler",
        default=os.environ.get("MUSCLEWRAP_SCHEDULER") or None,
        help="address of a dask.distributed scheduler to run the tasks on (default: "
        "$MUSCLEWRAP_SCHEDULER; none: this machine); needs the [dask] extra",
    )
    ru.add_argument(
        "--frames", help="START:STOP[:STEP] over the motion's rows, e.g. 0:211:1 (default all)"
    )
    ru.add_argument(
        "--workers", type=int, default=None, help="processes over muscles (default: CPU count)"
    )
    ru.add_argument(
        "--cache-dir", help="where preparations are cached (default ~/.cache/musclewrap)"
    )
    ru.add_argument("--no-cache", action="store_true", help="prepare every muscle afresh")
    ru.add_argument("--no-gif", action="store_true", help="skip scene.gif")
    ru.add_argument(
        "--no-collisions",
        action="store_true",
        help="let muscles pass through bones and each other (penetration is still measured "
        "and reported)",
    )
    ru.add_argument(
        "--no-fibres",
        action="store_true",
        help="skip writing the scene's [fibres] (fibres, their lengths and moment arms); "
        "their attachment areas are still held ([fibres] attached), so the surfaces are a "
        "run's with the fibres",
    )
    ru.add_argument(
        "--allow-unconverged", action="store_true", help="exit 0 even if a frame did not converge"
    )
    ru.add_argument(
        "--resume",
        action="store_true",
        help="go on from an interrupted run into the same OUTDIR (same scene, files and frames)",
    )

    ru.add_argument(
        "--no-check",
        action="store_true",
        help="skip the checks of 'musclewrap check' that run first (a scene they refuse "
        "would give a wrong result)",
    )


def _add_init(sub: _Commands) -> None:
    """The ``init`` sub-command's arguments."""
    it = sub.add_parser(
        "init",
        help="write a scene from an OpenSim model and a folder of meshes",
        description=(
            "Classify every mesh of MESH_DIR (muscle, bone, cartilage) by name and shape, match "
            "the muscles to the model's paths by anatomical name and the bones to its bodies, "
            "find the units, the rest pose and, for meshes of another subject, a registration "
            "from the cartilages; write a commented scene (each guess with how sure it is) and "
            "list what could not be placed. Then: musclewrap check SCENE."
        ),
    )
    it.add_argument("model", help="OpenSim model (.osim)")
    it.add_argument("mesh_dir", help="folder of meshes (.stl .vtk .vtp .ply .obj .off)")
    it.add_argument("-o", "--output", required=True, help="scene file to write (.toml)")
    it.add_argument(
        "--motion",
        help="motion to drive the scene (.mot/.sto); without one, a sweep of each driven "
        "coordinate over its range is written beside the scene",
    )
    it.add_argument(
        "--model-bones",
        action="store_true",
        help="where no bone of the folder is carried by a body that carries muscles (a thigh "
        "segmented without its femur), take the model's own meshes of that body "
        "([bones.NAME] model = FILE), said in the scene's comment",
    )
    it.add_argument("--force", action="store_true", help="write over an existing scene file")


def _add_check(sub: _Commands) -> None:
    """The ``check`` sub-command's arguments."""
    ck = sub.add_parser(
        "check",
        help="check a scene at its rest pose without deforming",
        description=(
            "Everything a run reads and validates, without deforming: per muscle the distance "
            "of its action lines to its mesh at rest and their length against its extent, "
            "repairs, overlaps at rest with bones and other muscles, units, bodies, and the "
            "coordinates the motion lacks; each finding with what to change. Exit status 0: "
            "clean (notes and warnings aside), 2: something would make a run wrong."
        ),
    )
    ck.add_argument("scene", help="scene file (.toml)")
    ck.add_argument("-o", "--output", help="picture of the rest pose (.png)")


def _add_demo(sub: _Commands) -> None:
    """The ``demo`` sub-command's arguments."""
    dm = sub.add_parser(
        "demo",
        help="run the embedded synthetic example: two muscles wrapping over a knee (no data needed)",
    )
    dm.add_argument("-o", "--output", default="musclewrap_demo", help="output folder")
    dm.add_argument("--frames", type=int, default=61, help="number of frames (at least 2)")
    dm.add_argument("--no-gif", action="store_true", help="skip scene.gif and scene.png")
    dm.add_argument(
        "--workers", type=int, help="worker processes (default: one per muscle, at most the CPUs)"
    )


def _add_view(sub: _Commands) -> None:
    """The ``view`` sub-command's arguments."""
    vw = sub.add_parser(
        "view",
        help="drag a joint in the browser and watch the muscles wrap (needs the [view] extra)",
        description=(
            "A local web page at http://127.0.0.1:PORT/ with a slider per coordinate the "
            "scene drives and a time slider; each change is solved as 'run' solves that pose "
            "(contact included) and drawn in the browser, with the update time, the volume "
            "error and the deepest penetration. Given a run's output folder instead of a "
            "scene, it plays the run's scene.pvd (time slider, play/pause) without solving."
        ),
    )
    vw.add_argument("source", help="scene file (.toml), or a run's output folder (with scene.pvd)")
    vw.add_argument("--port", type=int, help="port on 127.0.0.1 (default: a free one)")
    vw.add_argument("--no-browser", action="store_true", help="do not open a browser")
    vw.add_argument(
        "-o", "--output", default="musclewrap_poses",
        help="where 'Write this pose' writes its pose_NNN/ folders",
    )  # fmt: skip
    vw.add_argument(
        "--cache-dir", help="where preparations are cached (default ~/.cache/musclewrap)"
    )
    vw.add_argument("--no-collisions", action="store_true", help="as for run")
    vw.add_argument("--no-check", action="store_true", help="as for run")


def _add_bench(sub: _Commands) -> None:
    """The ``bench`` sub-command's arguments."""
    be = sub.add_parser("bench", help="run a benchmark")
    be.add_argument("name", choices=("capsule",), help="benchmark to run")
    be.add_argument("--repeats", type=int, default=41, help="timed repeats per case")
    be.add_argument(
        "--cage-coarsening",
        choices=("uniform", "quadric"),
        default="uniform",
        help="cage construction (quadric: the earlier decimation, for comparison)",
    )
    be.add_argument("--json", help="write the results as JSON here")


def _spare_inputs(inputs: Sequence[str | None], outputs: Sequence[str | None]) -> None:
    """Refuse an output path that names an input file (or another output)."""
    clash = overwrite_clash(inputs, outputs)
    if clash is not None:
        p, what = clash
        raise ValueError(
            f"{p}: this is {what} file of the command; musclewrap never writes over its "
            "inputs or one output over another: choose another output path"
        )


def _cmd_prepare(a: argparse.Namespace) -> int:
    from .constants import defaults
    from .solver import Muscle

    _spare_inputs([a.mesh], [a.output])
    m = Muscle.from_file(a.mesh, cage_size=a.cage_size or defaults.cage_size)
    m.save(a.output)
    c = m.cage
    print(
        f"prepared {a.mesh}: {len(m.V)} vertices, cage {len(c.C)} vertices "
        f"(volume x{c.volume_ratio:.2f}, margin {c.min_distance:.3g}), {m.seconds_prepare:.2f} s -> {a.output}"
    )
    for note in m.notes:
        print(f"  note: {note}")
    return 0


def _read_obstacle(path: str):  # noqa: ANN202
    """A bone file as an obstacle (`musclewrap.contact.bone_surface`: an open one is refused)."""
    from .contact import Obstacle, Placed, bone_surface
    from .mesh import read_mesh

    V, F, _ = bone_surface(*read_mesh(path), source=path)
    return Placed(Obstacle(V, F), name=Path(path).name)


def _cmd_deform(a: argparse.Namespace) -> int:
    import numpy as np

    from .conditions import read_lines_csv
    from .constants import defaults
    from .mesh import FORMATS, read_mesh, write_mesh
    from .solver import Muscle

    if (a.reference_rest is None) != (a.reference_current is None):
        raise ValueError("give both --reference-rest and --reference-current, or neither")
    if Path(a.output).suffix.lower() not in FORMATS:
        raise ValueError(
            f"{a.output}: unknown output format '{Path(a.output).suffix}'; use one of "
            + ", ".join(FORMATS)
        )
    _spare_inputs([a.mesh, a.rest, a.current, a.prepared, *a.bone], [a.output, a.report])
    if not (np.isfinite(a.margin) and a.margin >= 0):
        raise ValueError(f"--margin must be >= 0 (mesh units), got {a.margin}")
    obstacles = [_read_obstacle(b) for b in a.bone]
    rest = read_lines_csv(a.rest)
    cur = read_lines_csv(a.current)
    t0 = time.perf_counter()
    if a.prepared:
        from .mesh import clean_mesh

        muscle = Muscle.load(a.prepared)
        V, F, _ = clean_mesh(*read_mesh(a.mesh), source=a.mesh)
        if not (
            V.shape == muscle.V.shape
            and F.shape == muscle.F.shape
            and (V == muscle.V).all()
            and (F == muscle.F).all()
        ):
            raise ValueError(
                f"{a.prepared} was prepared from another mesh than {a.mesh}; run prepare again"
            )
        seconds_prepare = time.perf_counter() - t0
    else:
        muscle = Muscle.from_file(a.mesh, cage_size=a.cage_size or defaults.cage_size)
        seconds_prepare = muscle.seconds_prepare
    d = muscle.bind(rest, reference_point=a.reference_rest)
    res = d.deform(
        cur,
        reference_point=a.reference_current,
        method=a.method,
        obstacles=obstacles,
        margin=a.margin,
    )
    ok = res.converged  # includes the volume tolerance
    finite = bool(np.isfinite(res.V).all())
    if (ok or a.allow_unconverged) and finite:
        # VTP/VTK carry each vertex's index in the input file (other formats have no arrays)
        write_mesh(a.output, res.V, muscle.F, point_data={"input_id": muscle.input_id})
    report = {
        "n_vertices": int(len(muscle.V)),
        "n_cage_vertices": int(len(muscle.cage.C)),
        "volume_rest": res.volume_rest,
        "volume_deformed": res.volume,
        "relative_volume_error": res.relative_volume_error,
        "iterations": res.iterations,
        "converged": res.converged,
        "reason": res.reason,
        "skeleton_fit_mean": res.skeleton_fit_mean,
        "skeleton_fit_max": res.skeleton_fit_max,
        "energy": res.energy,
        "method": res.method,
        "contact_vertices": res.contact_vertices,
        "penetration_depth": res.penetration_depth,
        "penetration_depth_before": res.penetration_depth_before,
        "bone_inside_depth": res.bone_inside_depth,
        "shape_change_max": float(muscle.shape_change(res.V).max())
        if np.isfinite(res.V).all()
        else None,
        "cage_min_angle_deg": muscle.cage.min_angle_deg,
        "cage_coarsening": muscle.cage.method,
        "condition_number": d.condition_number,
        "seconds_prepare": seconds_prepare,
        "seconds_deform": res.seconds,
        "mesh_notes": list(muscle.notes),
        # per line: the arc-length fractions not bound at its start and end (tendons beyond
        # the mesh, `Deformer.unbound`) and the farthest of those samples from the muscle
        "lines_unbound": {k: list(v) for k, v in d.unbound.items()},
        "coordinates_precision": "float32 (STL format limit)"
        if a.output.lower().endswith(".stl")
        else "float64",
    }
    if a.report:
        from .mesh import atomic_path

        with atomic_path(a.report) as tmp:
            # strict JSON: a value that could not be computed is null, never NaN
            clean = {
                k: None if isinstance(v, float) and not np.isfinite(v) else v
                for k, v in report.items()
            }
            tmp.write_text(json.dumps(clean, indent=2, allow_nan=False), encoding="utf-8")
    print(
        f"{'converged' if res.converged else 'NOT converged'} in {res.iterations} iterations: "
        f"volume error {res.relative_volume_error:.2e}, skeleton fit {res.skeleton_fit_mean:.3g} (mean), "
        f"{res.seconds * 1e3:.1f} ms"
    )
    for line, (start, end, far) in d.unbound.items():
        print(
            f"note: line '{line}' is not bound over its first {100 * start:.0f} % and last "
            f"{100 * end:.0f} % (up to {far:.3g} outside the muscle: a tendon the mesh does "
            "not hold); the muscle follows the rest of it"
        )
    if not ok and not (a.allow_unconverged and finite):
        hint = " (use --allow-unconverged to write it anyway)" if finite else ""
        print(f"error: {res.reason}; no output written{hint}", file=sys.stderr)
        return 3
    return 0


def _workers(a: argparse.Namespace, muscles: int) -> int:
    """``--workers``, or one per muscle, at most the CPUs."""
    workers = a.workers if a.workers is not None else min(os.cpu_count() or 1, muscles)
    if workers < 1:
        raise ValueError(f"--workers must be at least 1, got {workers}")
    return workers


def _cmd_demo(a: argparse.Namespace) -> int:
    from .scene import load_scene, run_batch
    from .synthetic import write_knee_scene

    if a.frames < 2:
        raise ValueError(f"--frames must be at least 2, got {a.frames}")
    out = Path(a.output)
    # the demo is an ordinary scene, made by the package: written, then run as any other
    toml = write_knee_scene(out / "input", a.frames)
    scene = load_scene(toml)
    (summary,) = run_batch(
        [scene],
        [out],
        workers=_workers(a, len(scene.muscles)),
        progress=sys.stderr,
        render=False if a.no_gif else None,
        log=lambda m: print(m, file=sys.stderr),
    )
    print(summary.text())
    print(
        f"demo: two muscles over a knee's condyles, 0-90 deg of flexion in {a.frames} frames "
        f"-> {out}/scene.pvd"
        + ("" if a.no_gif else f", {out}/scene.gif (still: scene.png)")
        + f"; the scene: {toml} (musclewrap run {toml} -o DIR runs it again)"
    )
    return 0 if summary.unconverged == 0 else 3


def _cmd_run(a: argparse.Namespace) -> int:
    import dataclasses

    from .scene import load_scene, run_batch

    scenes = [load_scene(p) for p in a.scene]
    cache: Path | bool = False if a.no_cache else (Path(a.cache_dir) if a.cache_dir else True)
    if len(scenes) > 1 and not a.output:
        raise ValueError("several scenes: give the batch's output folder with -o")
    stems = [sc.path.stem for sc in scenes]
    if len(set(stems)) != len(stems):
        raise ValueError(
            "two scenes of the batch have the same file name ("
            + ", ".join(sorted({s for s in stems if stems.count(s) > 1}))
            + "): their output folders would clash"
        )
    if a.output:
        base = Path(a.output)
        outs = [base] if len(scenes) == 1 else [base / s for s in stems]
    else:
        outs = [scenes[0].path.parent / f"{scenes[0].path.stem}_out"]
    workers = _workers(a, sum(len(sc.muscles) for sc in scenes))
    runs, folders = [], []
    for scene, out in zip(scenes, outs, strict=True):
        if a.no_fibres and scene.fibres is not None:
            # the fibres are not written; their areas are still held ([fibres] attached),
            # so the surfaces are those of a run with the fibres
            fibres = dataclasses.replace(scene.fibres, output=False, moment_arms=())
            scene = dataclasses.replace(scene, fibres=fibres if fibres.attached else None)
        # several motions (e.g. sweeps): one output folder each
        if len(scene.motions) <= 1:
            runs.append(scene)
            folders.append(out)
        else:
            runs += [dataclasses.replace(scene, motions=(m,)) for m in scene.motions]
            folders += [out / m.stem for m in scene.motions]
    with contextlib.ExitStack() as stack:
        executor = None
        if not a.scheduler:
            from .run import local_executor

            # started before the check: the workers import while this process checks
            executor = local_executor(workers, sum(len(sc.muscles) for sc in runs), stack)
        if not a.no_check:
            from .scene import check_scene

            for sc in scenes:
                rep = check_scene(sc, cache_dir=cache)  # the run's cache: --no-cache writes none
                if not rep.ok:
                    from .run import refusal

                    print(f"error: {refusal(sc, rep)}", file=sys.stderr)
                    return 2
        if a.scheduler:
            from .run import connect

            executor = stack.enter_context(
                connect(a.scheduler, log=lambda m: print(m, file=sys.stderr))
            )
        summaries = run_batch(
            runs,
            folders,
            frames=a.frames,
            workers=workers,
            cache_dir=cache,
            progress=sys.stderr,
            render=False if a.no_gif else None,
            log=lambda m: print(m, file=sys.stderr),
            resume=a.resume,
            collisions=False if a.no_collisions else None,
            executor=executor,
        )
    unconverged = 0
    for sc, summary in zip(runs, summaries, strict=True):
        if len(runs) > 1:
            print(f"{sc.path.name}" + (f", motion {sc.motion.name}" if sc.motion else "") + ":")
        print(summary.text())
        unconverged += summary.unconverged
    if unconverged and not a.allow_unconverged:
        print(
            f"error: {unconverged} frame(s) did not converge (see report.csv, column "
            "'reason'); --allow-unconverged to accept",
            file=sys.stderr,
        )
        return 3
    return 0


def _cmd_init(a: argparse.Namespace) -> int:
    from .subject import init_scene

    out = Path(a.output)
    if out.suffix.lower() != ".toml":
        raise ValueError(f"{out}: the scene file must end in .toml")
    if out.exists() and not a.force:
        raise ValueError(f"{out}: exists; --force to write over it")
    inputs = [a.model, a.motion]
    if Path(a.mesh_dir).is_dir():
        inputs += [str(p) for p in Path(a.mesh_dir).iterdir()]
    _spare_inputs(inputs, [a.output, str(out.with_name(out.stem + "_sweep.mot"))])
    t = time.perf_counter()
    r = init_scene(
        Path(a.model),
        Path(a.mesh_dir),
        out,
        motion=Path(a.motion) if a.motion else None,
        model_bones=a.model_bones,
        log=lambda m: print(m, file=sys.stderr),
    )
    print(
        f"wrote {out} in {time.perf_counter() - t:.1f} s: {len(r.muscles)} muscles, "
        f"{len(r.bones)} bones"
        + (f"; a sweep motion {r.motion_written}" if r.motion_written else "")
    )
    for name, paths in r.muscles.items():
        print(f"  {name}: {', '.join(paths)}")
    if r.unplaced:
        print(f"not placed ({len(r.unplaced)}):")
        for u in r.unplaced:
            print(f"  {u}")
    print(f"next: musclewrap check {out}")
    return 0


def _print_findings(report, out) -> None:  # noqa: ANN001
    for f in report.findings:
        print(f"  {f}", file=out)


def _cmd_check(a: argparse.Namespace) -> int:
    from .scene import check_scene

    t = time.perf_counter()
    if a.output:
        _spare_inputs([a.scene], [a.output])
    rep = check_scene(a.scene, picture=a.output, log=lambda m: print(m, file=sys.stderr))
    counts = {lv: sum(f.level == lv for f in rep.findings) for lv in ("error", "warning", "note")}
    print(
        f"{a.scene}: {counts['error']} errors, {counts['warning']} warnings, {counts['note']} "
        f"notes ({time.perf_counter() - t:.1f} s)"
    )
    _print_findings(rep, sys.stdout)
    for name, fit in rep.fits.items():
        print(
            f"  {name}: lines {100 * fit.inside:.0f} % inside, nearest quarter within "
            f"{fit.near:.3g}, farthest {fit.far:.3g}; lines {fit.length:.4g} long, muscle "
            f"{fit.extent:.4g}, thickness {rep.thickness[name]:.3g}"
        )
    if rep.picture is not None:
        print(f"picture: {rep.picture}")
    return 0 if rep.ok else 2


def _cmd_view(a: argparse.Namespace) -> int:
    from .view import viewer

    if a.port is not None and not 0 < a.port < 65536:
        raise ValueError(f"--port must be 1..65535, got {a.port}")
    src = Path(a.source)
    kw = {}
    if not src.is_dir():
        kw = {
            "cache_dir": Path(a.cache_dir) if a.cache_dir else True,
            "check": not a.no_check,
            "collisions": False if a.no_collisions else None,
            "log": lambda m: print(m, file=sys.stderr),
            "prepare": False,  # in the solver thread, while the page loads
        }
    from .view import open_source

    t = time.perf_counter()
    source = open_source(src, **kw)  # a scene's check and reading: before the server starts
    app = viewer(source, output=a.output)
    print(f"{a.source}: ready in {time.perf_counter() - t:.1f} s", file=sys.stderr)
    app.start(a.port, open_browser=not a.no_browser)
    return 0


def _cmd_bench(a: argparse.Namespace) -> int:
    from ._bench import capsule_benchmark

    info, rows = capsule_benchmark(repeats=a.repeats, cage_coarsening=a.cage_coarsening)
    print(
        f"capsule: {int(info['n_vertices'])} vertices, cage {int(info['n_cage_vertices'])} "
        f"({info['cage_coarsening']}, min angle {info['cage_min_angle_deg']:.1f} deg), "
        f"prepare {info['seconds_prepare']:.2f} s (one-off start-up before it "
        f"{info['seconds_startup']:.2f} s), W@X {info['ms_W_at_X']:.2f} ms (median), "
        f"rows_dot 6 columns {info['ms_rows_dot_6']:.2f} ms = {info['ratio_rows_dot_6_to_WX']:.2f}x W@X"
    )
    print(
        f"{'scenario':<11}{'method':<7}{'it':>4}{'volume error':>14}{'fit mm':>8}{'shape':>7}"
        f"{'ms/pose':>9}{'x W@X':>7}"
    )
    for r in rows:
        print(
            f"{r['scenario']:<11}{r['method']:<7}{r['iterations']:>4}{r['relative_volume_error']:>14.2e}"
            f"{r['skeleton_fit_mean']:>8.3f}{r['shape_change_max']:>7.3f}"
            f"{r['ms_per_pose']:>9.2f}{r['ratio_to_WX']:>7.2f}"
        )
    if a.json:
        from .mesh import atomic_path

        with atomic_path(a.json) as tmp:
            tmp.write_text(json.dumps({"info": info, "rows": rows}, indent=2), encoding="utf-8")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status.

    0 ok, 2 bad input (the message names the file and the problem), 3 not converged,
    4 a failure of the machine or a worker process.
    """
    from .cage import CageError
    from .conditions import LineError
    from .mesh import MeshError

    args = _parser().parse_args(argv)
    helper = None
    if args.command in ("prepare", "deform", "run", "demo", "view"):
        from ._jit import compile_if_first_run

        helper = compile_if_first_run()  # a first run: a pose's kernels compile meanwhile
        if helper is not None and args.command in ("run", "demo", "view"):
            from ._jit import compile_here

            compile_here()  # this process's share, before the run's workers start
            helper.wait()  # and the helper's: no worker compiles a kernel of its own
    handlers = {
        "prepare": _cmd_prepare,
        "deform": _cmd_deform,
        "run": _cmd_run,
        "demo": _cmd_demo,
        "bench": _cmd_bench,
        "init": _cmd_init,
        "check": _cmd_check,
        "view": _cmd_view,
    }
    try:
        return handlers[args.command](args)
    except (MeshError, LineError, CageError, ValueError, OSError, ImportError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except RuntimeError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 4
    finally:
        if helper is not None:
            helper.wait()  # done already, unless the command needed no pose


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
