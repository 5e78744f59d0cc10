"""Compiled kernels of `musclewrap.mesh` that other packages' compiled loops call.

Numba compiles a kernel's callees into it, so a compiled loop elsewhere (the solver's
proxy iteration) imports the kernels themselves, not their Python wrappers; this module
says which ones it may.
"""

from ._cubic import root_near
from ._volume import _cubic_pair_ser as cubic_pair_ser
from ._volume import _gradient_kernel as gradient_kernel
from ._volume import _mean_rows_kernel as mean_rows_kernel

__all__ = ["cubic_pair_ser", "gradient_kernel", "mean_rows_kernel", "root_near"]
