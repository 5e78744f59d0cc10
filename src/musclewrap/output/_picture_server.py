"""A renderer process: draws pictures of written meshes off screen, on request.

Run as a script (``python _picture_server.py``), not imported: it needs only VTK and
NumPy, so it starts in about 0.4 s (importing musclewrap, with Numba, and PyVista's
plotter took about 2 s). VTK can crash the process at the first render where no
OpenGL backend exists; the process that started this one reads that as a clear error
(`._render.Renderer`).

Protocol: it opens an off-screen window and prints ``ready``; then, for each line of
JSON read on stdin (a request: see `._render.PictureTask`), it draws the pictures
into the ``.npy`` file the request names and prints ``done``. End of input: it exits.
"""

from __future__ import annotations

import json
import sys


def main() -> int:
    import numpy as np
    import vtkmodules.vtkRenderingFreeType  # noqa: F401  # the time label's fonts
    import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  # the OpenGL implementation
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkUnsignedCharArray
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader
    from vtkmodules.vtkRenderingCore import (
        vtkActor,
        vtkLightKit,
        vtkPolyDataMapper,
        vtkRenderer,
        vtkRenderWindow,
        vtkTextActor,
    )

    window = vtkRenderWindow()
    window.SetOffScreenRendering(1)
    # no multisampling: in a software OpenGL (llvmpipe, what a server without a GPU has)
    # 4x MSAA tripled the time of a picture, and a 256-colour GIF keeps little of it
    window.SetMultiSamples(0)
    window.SetSize(64, 64)
    window.Render()  # the OpenGL context now: a missing backend fails here, before any work
    print("ready", flush=True)

    def read(path: str) -> object:
        r = vtkXMLPolyDataReader()
        r.SetFileName(path)
        r.Update()
        if r.GetErrorCode():
            raise OSError(f"{path}: not a readable VTK PolyData file")
        return r.GetOutput()

    def draw(req: dict) -> None:
        w, h = req["size"]
        folder = req["folder"]
        ren = vtkRenderer()
        ren.SetBackground(1.0, 1.0, 1.0)
        ren.AutomaticLightCreationOff()
        vtkLightKit().AddLightsToRenderer(ren)
        window.GetRenderers().RemoveAllItems()
        window.AddRenderer(ren)
        window.SetSize(w, h)
        label = vtkTextActor()
        prop = label.GetTextProperty()
        prop.SetFontSize(int(req.get("font", 20)))
        prop.SetColor(0.0, 0.0, 0.0)
        prop.SetVerticalJustificationToTop()
        label.SetDisplayPosition(4, h - 4)
        ren.AddViewProp(label)
        shown: dict[str, tuple[str, object]] = {}  # part -> (file, mapper)

        def show(files: list[list[str]]) -> None:
            # files: (part, kind, file); kind "line", "bone" or a muscle's "r,g,b"
            for part, kind, f in files:
                if part in shown and shown[part][0] == f:
                    continue  # a static bone: read once
                mesh = read(f"{folder}/{f}")
                if part in shown:
                    shown[part][1].SetInputData(mesh)
                    shown[part] = (f, shown[part][1])
                    continue
                mapper = vtkPolyDataMapper()
                mapper.SetInputData(mesh)
                actor = vtkActor()
                actor.SetMapper(mapper)
                p = actor.GetProperty()
                if kind == "line":
                    p.SetColor(0.0, 0.0, 0.0)
                    p.SetLineWidth(3.0)
                else:
                    p.SetColor(*(float(c) for c in kind.split(",")))
                    # muscles and bones are closed and face outward: the same picture
                    # (1 pixel in 480,000 differed on the LHDL walk) at 0.6 of the time
                    p.BackfaceCullingOn()
                ren.AddActor(actor)
                shown[part] = (f, mapper)

        # the first time step places the camera, the same for every request of a series:
        # along the scene's thinnest extent, its longest one up (a side view of a limb
        # whatever the frame's convention), fixed for the whole motion
        show(req["camera"])
        b = np.array(ren.ComputeVisiblePropBounds(), dtype=float).reshape(3, 2)
        ext = np.diff(b, axis=1).ravel()
        centre = b.mean(axis=1)
        look, up = np.zeros(3), np.zeros(3)
        look[int(np.argmin(ext))] = 1.0
        up[int(np.argmax(ext))] = 1.0
        cam = ren.GetActiveCamera()
        cam.SetFocalPoint(*centre)
        cam.SetPosition(*(centre + look))
        cam.SetViewUp(*up)
        ren.ResetCamera()
        cam.Zoom(1.05)
        pictures = np.empty((len(req["steps"]), h, w, 3), dtype=np.uint8)
        pixels = vtkUnsignedCharArray()
        for i, (t, files) in enumerate(req["steps"]):
            show(files)
            label.SetInput(f"t = {t:.3f}")
            window.Render()
            window.GetPixelData(0, 0, w - 1, h - 1, 0, pixels, 0)  # the back buffer: just drawn
            pictures[i] = vtk_to_numpy(pixels).reshape(h, w, 3)[::-1]  # rows run bottom-up
        np.save(req["out"], pictures)

    for line in sys.stdin:
        req = json.loads(line)
        try:
            draw(req)
        except Exception as exc:  # noqa: BLE001  # said to the requester, which goes on
            print(f"error: {exc}".replace("\n", " "), flush=True)
            continue
        print("done", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
