"""A renderer process: draws pictures of written meshes off screen, on request.

Run as a script (``python _picture_server.py``), not imported: it needs only VTK and
NumPy, so it starts in about 0.4 s, where importing musclewrap (with Numba) and
building PyVista's plotter took about 1.7 s (`benchmarks/speed/bench_pictures.py`). VTK can crash the process at the first render where no
OpenGL backend exists; the process that started this one reads that as a clear error
(`._render.Renderer`).

Protocol: it opens an off-screen window and prints ``ready``; then, for each line of
JSON read on stdin (a request: see `._render.PictureTask`), it draws the pictures
into the ``.npy`` file the request names and prints ``done``. End of input: it exits.
"""

from __future__ import annotations

import json
import sys

import numpy as np
import vtkmodules.vtkRenderingFreeType  # noqa: F401  # the time label's fonts
import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  # the OpenGL implementation
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkLookupTable, vtkUnsignedCharArray
from vtkmodules.vtkIOXML import vtkXMLPolyDataReader
from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor
from vtkmodules.vtkRenderingCore import (
    vtkActor,
    vtkLightKit,
    vtkPolyDataMapper,
    vtkRenderer,
    vtkRenderWindow,
    vtkTextActor,
)


def _read(path: str) -> object:
    r = vtkXMLPolyDataReader()
    r.SetFileName(path)
    r.Update()
    if r.GetErrorCode():
        raise OSError(f"{path}: not a readable VTK PolyData file")
    return r.GetOutput()


class _Scene:
    """One request's scene in the window: what it shows, read once per file."""

    def __init__(
        self,
        window: vtkRenderWindow,
        folder: str,
        w: int,
        h: int,
        stretch_range: list,
        stretch_table: list,
    ) -> None:
        self.window, self.folder, self.w, self.h = window, folder, w, h
        self.stretch_range = (float(stretch_range[0]), float(stretch_range[1]))
        self.stretch_table = stretch_table
        self.lut: vtkLookupTable | None = None
        self.ren = vtkRenderer()
        self.ren.SetBackground(1.0, 1.0, 1.0)
        self.ren.AutomaticLightCreationOff()
        vtkLightKit().AddLightsToRenderer(self.ren)
        window.GetRenderers().RemoveAllItems()
        window.AddRenderer(self.ren)
        window.SetSize(w, h)
        self.label = vtkTextActor()
        prop = self.label.GetTextProperty()
        prop.SetFontSize(20)
        prop.SetColor(0.0, 0.0, 0.0)
        prop.SetVerticalJustificationToTop()
        self.label.SetDisplayPosition(4, h - 4)
        self.ren.AddViewProp(self.label)
        self.shown: dict[str, tuple[str, vtkPolyDataMapper]] = {}  # part -> (file, mapper)
        self.pixels = vtkUnsignedCharArray()

    def show(self, files: list[list[str]]) -> None:
        """Show (part, drawn as, file) triples: "line" (black), or a colour "r,g,b"."""
        for part, kind, f in files:
            if part in self.shown and self.shown[part][0] == f:
                continue  # a static bone: read once
            mesh = _read(f"{self.folder}/{f}")
            if part in self.shown:
                mapper = self.shown[part][1]
                mapper.SetInputData(mesh)
                self.shown[part] = (f, mapper)
                continue
            mapper = vtkPolyDataMapper()
            mapper.SetInputData(mesh)
            mapper.ScalarVisibilityOff()
            actor = vtkActor()
            actor.SetMapper(mapper)
            p = actor.GetProperty()
            if kind == "line":
                p.SetColor(0.0, 0.0, 0.0)
                p.SetLineWidth(3.0)
            elif kind == "stretch":
                mapper.SetLookupTable(self.stretch_colours())
                mapper.SetScalarModeToUsePointFieldData()
                mapper.SelectColorArray("area_stretch")
                mapper.SetScalarRange(*self.stretch_range)
                mapper.UseLookupTableScalarRangeOn()
                mapper.ScalarVisibilityOn()
                p.BackfaceCullingOn()
            else:
                p.SetColor(*(float(c) for c in kind.split(",")))
                # muscles and bones are closed and face outward: the same picture
                # (1 pixel in 480,000 differed on the LHDL walk) at 0.6 of the time
                p.BackfaceCullingOn()
            self.ren.AddActor(actor)
            self.shown[part] = (f, mapper)

    def stretch_colours(self) -> vtkLookupTable:
        """Blue (compressed) through white to red (stretched), in equal ratios; a bar.

        The request's table (`._render.stretch_table`), on a log scale over its range.
        """
        if self.lut is None:
            lo, hi = self.stretch_range
            lut = vtkLookupTable()
            lut.SetScaleToLog10()
            lut.SetRange(lo, hi)
            lut.SetNumberOfTableValues(len(self.stretch_table))
            for i, rgb in enumerate(self.stretch_table):
                lut.SetTableValue(i, *rgb, 1.0)
            lut.Build()
            bar = vtkScalarBarActor()
            bar.SetLookupTable(lut)
            bar.SetTitle("area stretch")
            bar.SetNumberOfLabels(5)
            bar.SetLabelFormat("%.2f")
            bar.SetOrientationToHorizontal()
            bar.SetPosition(0.62, 0.03)
            bar.SetWidth(0.35)
            bar.SetHeight(0.09)
            for prop in (bar.GetTitleTextProperty(), bar.GetLabelTextProperty()):
                prop.SetColor(0.0, 0.0, 0.0)
                prop.ShadowOff()
                prop.ItalicOff()
            self.ren.AddViewProp(bar)
            self.lut = lut
        return self.lut

    def place_camera(self, view: dict) -> None:
        """The series' camera (`._render.View`), the same for every request of a series."""
        cam = self.ren.GetActiveCamera()
        cam.SetFocalPoint(*view["focal"])
        cam.SetPosition(*view["position"])
        cam.SetViewUp(*view["up"])
        cam.SetViewAngle(view["angle"])

    def picture(self, t: float) -> np.ndarray:
        """Render once, labelled with the time, and read the back buffer (just drawn)."""
        self.label.SetInput(f"t = {t:.3f}")
        self.ren.ResetCameraClippingRange()
        self.window.Render()
        self.window.GetPixelData(0, 0, self.w - 1, self.h - 1, 0, self.pixels, 0)
        return vtk_to_numpy(self.pixels).reshape(self.h, self.w, 3)[::-1]  # rows run bottom-up


def draw(window: vtkRenderWindow, req: dict) -> None:
    """A request: its pictures, into the ``.npy`` file it names."""
    w, h = req["size"]
    scene = _Scene(window, req["folder"], w, h, req["stretch_range"], req["stretch_table"])
    scene.place_camera(req["view"])
    pictures = np.empty((len(req["steps"]), h, w, 3), dtype=np.uint8)
    for i, (t, files) in enumerate(req["steps"]):
        scene.show(files)
        pictures[i] = scene.picture(t)
    np.save(req["out"], pictures)


def main() -> int:
    window = vtkRenderWindow()
    window.SetOffScreenRendering(1)
    # no multisampling: in a software OpenGL (llvmpipe, what a server without a GPU has)
    # 4x MSAA tripled the time of a picture, and a 256-colour GIF keeps little of it
    window.SetMultiSamples(0)
    window.SetSize(64, 64)
    window.Render()  # the OpenGL context now: a missing backend fails here, before any work
    print("ready", flush=True)
    for line in sys.stdin:
        try:
            draw(window, json.loads(line))
        except Exception as exc:  # noqa: BLE001  # said to the requester, which goes on
            print(f"error: {exc}".replace("\n", " "), flush=True)
            continue
        print("done", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
