"""The grid kernels' old home: they live in the leaf :mod:`shapeverify.measures._grid_kernels`
(the characteristics use them too, without running the inspection package)."""

from ..measures._grid_kernels import (CELLS_PER_POINT, MARGIN, MIN_CELLS,  # noqa: F401
                                      any_within, count_within, kernel_array, kernel_sums,
                                      mark_within, nearest_other)
