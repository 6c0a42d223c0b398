"""Names rdgpu generates beside the user's (issue 19, A2's kin): the xarray Dataset of a
run (``param_<name>``, ``height``, coordinates, dimensions, the ``param_fields``
attribute), a sweep's Dataset (``pattern``, ``done``, ``batch``) and the NPZ data files
and checkpoints (``final_<s>``, ``param_<k>``, ``field__<s>``...).  A clash is refused
with a message naming both, never one value silently overwriting the other; where the
format keeps names apart by construction, a round trip proves it."""

from __future__ import annotations

from importlib.util import find_spec

import numpy as np
import pytest

import rdgpu
from rdgpu import Simulation, define_model
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.grid import Grid
from rdgpu.io.output import load_npz, save_npz

needs_xarray = pytest.mark.skipif(find_spec("xarray") is None, reason="needs xarray")
needs_dask = pytest.mark.skipif(
    any(find_spec(m) is None for m in ("dask", "distributed", "xarray", "zarr")),
    reason='needs the dask extra: pip install "rdgpu[dask]"')

#: a species named like the Dataset variable of parameter field F
SHADOW = define_model("shadow", {"u": "0.1*laplace(u) - F*u",
                                 "param_F": "0.1*laplace(param_F) - 2*param_F"},
                      {"F": 0.1})
INIT = {"kind": "square", "values": {"u": 1.0, "param_F": 2.0},
        "inside": {"u": 0.5, "param_F": 0.2}}


def _shadow_result():
    F = np.full((4, 4), 0.3)
    sim = Simulation(SHADOW, Grid((4, 4)), {"F": F}, dt=0.1, backend="numpy",
                     init=INIT)
    return sim.run(2)


@needs_xarray
def test_species_named_like_a_parameter_field_variable():
    with pytest.raises(ValueError, match=r"species names \['param_F'\] clash with the "
                       r"Dataset's own names \('param_F' is the variable of parameter field "
                       r"'F'.*rename the species"):
        _shadow_result().to_xarray()


@needs_xarray
def test_scalar_parameter_named_fields():
    m = define_model("m", {"u": "-fields*u"}, {"fields": 2.0})
    r = Simulation(m, Grid((4, 4)), dt=0.1, backend="numpy").run(1)
    with pytest.raises(ValueError, match=r"scalar parameter 'fields' would be the attribute "
                       r"'param_fields'.*rename the parameter"):
        r.to_xarray()


@needs_xarray
def test_species_named_height_on_a_graph_surface():
    m = define_model("m", {"height": "0.1*laplace(height) - height"}, {})
    r = Simulation(m, GraphSurface((4, 4), height=np.zeros((4, 4))), dt=0.01,
                   backend="numpy").run(1)
    with pytest.raises(ValueError, match=r"\['height'\] clash.*'height' is the surface height"):
        r.to_xarray()


@needs_xarray
def test_species_named_like_a_mesh_dimension():
    m = define_model("m", {"vertex": "0.1*laplace(vertex) - vertex"}, {})
    r = Simulation(m, rdgpu.SurfaceMesh.icosphere(1), dt=0.01, backend="numpy").run(1)
    with pytest.raises(ValueError, match=r"\['vertex'\] clash.*'vertex' is a dimension"):
        r.to_xarray()


def test_data_file_keeps_the_names_apart(tmp_path):
    r = _shadow_result()
    back = load_npz(save_npz(tmp_path / "run.npz", r))
    assert set(back.fields) == {"u", "param_F"}
    np.testing.assert_array_equal(back.fields["param_F"], r.fields["param_F"])
    np.testing.assert_array_equal(back.params["F"], r.params["F"])
    assert not np.array_equal(back.fields["param_F"], back.params["F"])


def test_checkpoint_keeps_the_names_apart(tmp_path):
    F = np.full((4, 4), 0.3)
    sim = Simulation(SHADOW, Grid((4, 4)), {"F": F}, dt=0.1, backend="numpy",
                     init=INIT)
    sim.run(2)
    path = sim.save_checkpoint(tmp_path / "ck.npz")
    back = Simulation.resume(path)
    for s in ("u", "param_F"):
        np.testing.assert_array_equal(back.host_state()[s], sim.host_state()[s])
    np.testing.assert_array_equal(np.asarray(back.params["F"]), F)


@needs_dask
@pytest.mark.parametrize("equations, swept, match", [
    ({"pattern": "-F*pattern", "u": "-u"}, {"F": [0.1, 0.2]},
     "a sweep cannot hold species pattern: the Dataset uses .*rename the species"),
    ({"u": "-u", "done": "-done"}, {"F": [0.1, 0.2]}, "cannot hold species done"),
    ({"batch": "-F*batch"}, {"F": [0.1, 0.2]}, "cannot hold species batch"),
    ({"u": "-F*u"}, {"done": [0.1, 0.2]}, "a swept parameter may not be called done"),
])
def test_sweep_refuses_its_own_names(equations, swept, match):
    params = {"F": 0.1, **{k: 0.1 for k in swept}}
    m = define_model("m", equations, params)
    with pytest.raises(ValueError, match=match):
        rdgpu.sweep(m, swept, steps=1, size=4, backend="numpy", scheduler="serial",
                    progress=False)
