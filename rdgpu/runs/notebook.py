"""A sweep's Dataset in a notebook: the ``ds.rdgpu`` accessor (`SweepView`).

Registered on ``xarray.Dataset`` by `register` when `rdgpu.runs.sweep` first loads xarray
(`rdgpu.runs.sweep.sweep`, `rdgpu.runs.sweep.open_sweep`), so that ``import rdgpu`` stays
free of xarray.  Jupyter shows ``ds.rdgpu`` as the parameter map (`_repr_png_`, drawn by
`rdgpu.runs.mosaic.sweep_map_png`) or as a table of the swept ranges, the count of each
pattern class and the wall time (`_repr_html_`).
"""

from __future__ import annotations

import html
from collections import Counter
from typing import Any

from rdgpu.runs.mosaic import sweep_map_png

__all__ = ["SweepView", "register"]

#: the accessor's name: ``ds.rdgpu``
NAME = "rdgpu"


def register(xr: Any) -> None:
    """Register `SweepView` as ``xarray.Dataset.rdgpu`` (once; ``xr`` is the xarray module)."""
    if not hasattr(xr.Dataset, NAME):
        xr.register_dataset_accessor(NAME)(SweepView)


class SweepView:
    """A sweep's Dataset as Jupyter shows it: ``ds.rdgpu``.

    Parameters
    ----------
    ds : xarray.Dataset
        A sweep's Dataset: ``pattern`` on the swept axes (class names, ``""``: not run
        yet), one field per species and the attrs that `rdgpu.runs.sweep.sweep` writes.

    Examples
    --------
    In a notebook, a cell ending in ``ds.rdgpu`` shows the parameter map;
    ``ds.rdgpu.summary()`` gives the counts as a dict.
    """

    def __init__(self, ds: Any) -> None:
        self._ds = ds
        #: the wall time in seconds of the `rdgpu.runs.sweep.sweep` call that made ``ds``
        #: (None: opened from a file, or derived from another Dataset)
        self.wall_s: float | None = None

    def swept(self) -> dict[str, tuple[float, float, int]]:
        """Each swept parameter's ``(first, last, number of values)``."""
        return {str(d): (float(self._ds[d].values[0]), float(self._ds[d].values[-1]),
                         int(self._ds.sizes[d])) for d in self._ds["pattern"].dims}

    def summary(self) -> dict[str, int]:
        """The number of members of each pattern class (``"not run"``: batches to come)."""
        names = [str(x) for x in self._ds["pattern"].values.ravel()]
        return {(k or "not run"): n for k, n in sorted(Counter(names).items())}

    def _repr_png_(self) -> bytes:
        """The parameter map (`rdgpu.runs.mosaic.sweep_map_png`), about 600 pixels wide."""
        field = self._ds[[v for v in self._ds.data_vars if v not in ("pattern", "done")][0]]
        cells = max(field.shape[-1], 1) * max(self._ds["pattern"].shape[0], 1)
        return sweep_map_png(self._ds, scale=max(1, 600 // cells))

    def _repr_html_(self) -> str:
        """A table: the swept ranges, the count of each class, the settings, the wall time."""
        a = self._ds.attrs
        rows = [f"<tr><th>{html.escape(k)}</th><td>{lo:.4g} … {hi:.4g} ({n} values)</td></tr>"
                for k, (lo, hi, n) in self.swept().items()]
        counts = ", ".join(f"{html.escape(k)}: {n}" for k, n in self.summary().items())
        rows.append(f"<tr><th>pattern</th><td>{counts}</td></tr>")
        fixed = ", ".join(f"{k[6:]} = {v:.4g}" for k, v in a.items()
                          if k.startswith("param_") and isinstance(v, (int, float)))
        if fixed:
            rows.append(f"<tr><th>fixed</th><td>{html.escape(fixed)}</td></tr>")
        run = f"{a.get('steps', '?')} steps of dt = {a.get('dt', '?')} on {a.get('backend', '?')}"
        rows.append(f"<tr><th>run</th><td>{html.escape(run)}</td></tr>")
        wall = "not recorded" if self.wall_s is None else f"{self.wall_s:.3g} s"
        rows.append(f"<tr><th>wall time</th><td>{wall}</td></tr>")
        title = html.escape(f"rdgpu sweep of {a.get('model', '?')}")
        return f"<table><caption>{title}</caption>{''.join(rows)}</table>"
