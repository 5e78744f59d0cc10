"""musclewrap: volume-exact deformation of muscle surface meshes driven by action lines.

The method follows Kohout, Kellnhofer & Martelli, "Fast deformation for
modelling of musculoskeletal system" (GRAPP 2012): a cage, mean value
coordinates, Laplacian and skeleton conditions and a hard volume constraint
on the fine mesh.
"""

from ._version import __version__
from .conditions import PathLines, read_lines_csv
from .mesh import read_mesh, write_mesh
from .solver import DeformationResult, Deformer, Muscle, deform

__all__ = [
    "DeformationResult",
    "Deformer",
    "Muscle",
    "PathLines",
    "__version__",
    "deform",
    "read_lines_csv",
    "read_mesh",
    "write_mesh",
]
