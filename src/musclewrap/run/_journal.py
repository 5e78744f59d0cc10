"""What a run has finished, kept beside its outputs so that an interrupted run can go on."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

from ..errors import SceneError
from ..mesh import atomic_path
from ._files import JOURNAL

__all__ = ["Journal"]

#: folder inside the output folder; removed when the run completes


class Journal:
    """Finished frame chunks and comparisons of one run, one small JSON file each.

    A chunk's file is written (atomically) only after all of its frames' files
    are, so a chunk found here is complete on disk. ``run.json`` holds a hash
    of every input and setting and the chunk layout; `--resume` goes on only
    from a journal with the same hash.

    Parameters
    ----------
    outdir : pathlib.Path
        The run's output folder.
    key : str
        Hash of the scene file, every file it names, the frames and the version.
    chunks : list of (int, int)
        Frame ranges of this run (indices into its frames), used unless resuming.
    resume : bool
        Go on from a journal found in ``outdir``.
    """

    def __init__(self, outdir: Path, key: str, chunks: list[tuple[int, int]], resume: bool) -> None:
        self.dir = outdir / JOURNAL
        self.notes: list[str] = []
        manifest = self.dir / "run.json"
        # temporary files of writes a kill interrupted (never renamed onto an output)
        stale = [p for p in outdir.rglob(".*.part.*") if p.is_file()] if outdir.is_dir() else []
        for p in stale:
            p.unlink(missing_ok=True)
        if stale:
            self.notes.append(
                f"removed {len(stale)} unfinished temporary file(s) of an earlier run"
            )
        if resume and manifest.is_file():
            try:
                meta = json.loads(manifest.read_text(encoding="utf-8"))
                old_key, old_chunks = meta["key"], [tuple(c) for c in meta["chunks"]]
            except (ValueError, KeyError, TypeError):
                raise SceneError(
                    f"{manifest}: the record of the interrupted run is damaged; run again "
                    "without --resume"
                ) from None
            if old_key != key:
                raise SceneError(
                    f"{outdir}: the scene, a file it names, the frames or musclewrap itself "
                    "changed since the interrupted run; run again without --resume (or into "
                    "another folder)"
                )
            self.chunks = old_chunks
            done = sum(1 for _ in self.dir.glob("chunk-*.json"))
            self.notes.append(f"resumed: {done} finished chunk(s) of frames kept")
            return
        if resume:
            self.notes.append(f"--resume: no interrupted run in {outdir}; all frames run")
        shutil.rmtree(self.dir, ignore_errors=True)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.chunks = [(int(a), int(b)) for a, b in chunks]
        self._write(manifest, {"key": key, "chunks": self.chunks})

    @staticmethod
    def _write(path: Path, data: Any) -> None:
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(data), encoding="utf-8")

    def _read(self, path: Path) -> Any:
        if not path.is_file():
            return None
        try:
            return json.loads(path.read_text(encoding="utf-8"))
        except ValueError:
            return None  # a damaged record: that part is run again

    def chunk(self, name: str, a: int, b: int) -> dict[str, Any] | None:
        """A finished chunk's result, or None."""
        part = self._read(self.dir / f"chunk-{name}-{a}-{b}.json")
        if part is None:
            return None
        part["entries"] = [tuple(e) for e in part["entries"]]
        return part  # type: ignore[no-any-return]

    def save_chunk(self, name: str, a: int, b: int, part: dict[str, Any]) -> None:
        self._write(self.dir / f"chunk-{name}-{a}-{b}.json", part)

    def comparison(self, name: str) -> dict[str, Any] | None:
        """A finished comparison with the paper's iteration, or None."""
        return self._read(self.dir / f"compare-{name}.json")  # type: ignore[no-any-return]

    def save_comparison(self, name: str, result: dict[str, Any]) -> None:
        self._write(self.dir / f"compare-{name}.json", result)

    @staticmethod
    def finish(outdir: Path) -> None:
        """The run in ``outdir`` is complete: nothing left to resume."""
        shutil.rmtree(outdir / JOURNAL, ignore_errors=True)
