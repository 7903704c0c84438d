"""The measuring blocks the inspection and the characteristics share (a leaf package).

It imports nothing of :mod:`shapeverify.inspection` or :mod:`shapeverify.characteristics` (only
numpy, numba, scipy and the package's top-level leaves ``_arrays``, ``errors``, ``units``), so
the characteristics evaluate on these blocks without running the inspection package, which runs
the characteristics of a plan (issue 31: no import cycle between folders, not even through a
package's ``__init__``).  This ``__init__`` imports nothing: importing one block costs only it.

* :mod:`.tolerance` -- :class:`~.tolerance.Tolerance`, the zone ``lower <= deviation <= upper``;
* :mod:`.checks` -- :func:`~.checks.check_scan` (a scan's validation) and
  :func:`~.checks.default_evaluation_distance` (the one default);
* :mod:`.codes` -- the reason codes of a deviation (``EVALUATED``, ``TOO_FAR``, ``ON_BOUNDARY``,
  ``OUTSIDE_FACES``);
* :mod:`.spacing` -- a point cloud's spacing (:func:`~.spacing.median_spacing`) and the
  neighbourhood median of deviations (:func:`~.spacing.neighbourhood_median`);
* :mod:`._grid_kernels` -- numba kernels of neighbour questions on a uniform grid.

The public names keep their old homes: ``shapeverify.inspection.Tolerance``,
``shapeverify.inspection.checks.check_scan``, ``shapeverify.inspection.deviations.TOO_FAR``,
``shapeverify.inspection.regions.median_spacing`` ... re-export these objects.
"""
