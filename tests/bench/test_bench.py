"""rdgpu.bench and ``rdgpu bench``: the record's fields, the Markdown table, the check
refusing a peer that computes something else, the sizes and cache read off a sweep, the
command's errors.  Never a timed assertion."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from rdgpu.bench import machine, report
from rdgpu.bench.contenders import Contender, rdgpu_contenders
from rdgpu.bench.machine import MiB, effective_llc, grid_sizes
from rdgpu.bench.peers import PEERS, peer_contenders, peer_status
from rdgpu.bench.problem import Runner, real_state, stepper
from rdgpu.bench.report import markdown, write
from rdgpu.bench.run import Options, check_options, run_bench
from rdgpu.cli.app import main
from rdgpu.cli.bench_options import PEER_NAMES


def _wrong_make(u, v):
    """The problem with F off by 10 %: a peer doing other maths."""
    st = stepper(u.shape, u.dtype, "numpy")
    st.set_state({"u": u, "v": v})
    p = dict(st.params)
    st2 = st.model.stepper(st.domain, {**{k: p[k] for k in ("Du", "Dv", "k")},
                                       "F": 0.0385}, dt=st.dt, backend="numpy",
                           dtype=u.dtype)
    st2.set_state({"u": u, "v": v})

    def state():
        s = st2.get_state()
        return s["u"], s["v"]

    return Runner(st2.advance, state)


@pytest.fixture(scope="module")
def record():
    mine = [c for c in rdgpu_contenders(["numpy"]) if c.name == "rdgpu numpy"]
    wrong = Contender("wrong peer", "peer", "0", _wrong_make)
    opts = Options(backends=["numpy"], dims=[2], dtypes=["float32"], sizes={2: [64]},
                   seconds=0.01, triad_max=2 * MiB, triad_seconds=0.001)
    with pytest.MonkeyPatch.context() as mp:  # NumPy's triad: no numba compilation
        mp.setattr(machine, "_numba_triad", lambda: None)
        return run_bench(opts, contenders=mine + [wrong])


def test_record_has_the_machine_and_rows(record):
    m = record["machine"]
    assert {"cpu", "cores", "versions", "triad", "dram_GBps", "cache_GBps", "llc"} <= set(m)
    assert m["triad"]["points"] and m["versions"]["rdgpu"]
    ok = next(r for r in record["rows"] if r["contender"] == "rdgpu numpy")
    assert ok["status"] == "ok" and ok["mcells"] > 0 and ok["compile_s"] >= 0
    assert (ok["dims"], ok["dtype"], ok["size"], ok["cells"]) == (2, "float32", 64, 4096)
    assert ok["roofline_mcells"] > 0 and ok["bytes_per_cell"] == 16
    json.dumps(record, default=str)


def test_a_wrong_peer_is_refused_and_not_timed(record):
    row = next(r for r in record["rows"] if r["contender"] == "wrong peer")
    assert row["status"] == "refused" and "disagrees" in row["note"]
    assert "mcells" not in row


def test_markdown_table(record):
    text = markdown(record)
    assert "| contender | version | compile s | 64² |" in text
    assert "| wrong peer | 0 |" in text and "refused" in text
    assert "Machine:" in text and "Triad" in text


def test_write_gives_the_files(record, tmp_path, monkeypatch):
    monkeypatch.setattr(report, "plot", lambda rec, path: path.write_bytes(b"png") and None)
    assert write(record, tmp_path) == []
    assert json.loads((tmp_path / "bench.json").read_text())["rows"]
    assert (tmp_path / "bench.md").read_text() == markdown(record)
    assert (tmp_path / "bench.png").exists()


def test_no_matplotlib_no_plot_and_a_note(record, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    assert "matplotlib is missing" in write(record, tmp_path)[0]
    assert not (tmp_path / "bench.png").exists()


def test_effective_llc_from_a_sweep():
    sweep = {"points": [[MiB, 100.0], [8 * MiB, 95.0], [64 * MiB, 90.0],
                        [256 * MiB, 20.0], [1024 * MiB, 15.0]]}
    got = effective_llc(sweep)
    assert got["llc"] == 64 * MiB and got["dram_GBps"] == 15.0
    flat = {"points": [[MiB, 10.0], [4 * MiB, 9.5]]}
    assert effective_llc(flat)["llc"] is None


def test_grid_sizes_in_cache_and_beyond():
    llc = 64 * MiB
    small, large = grid_sizes(llc, 2, 16, 64)
    assert small * small * 16 <= llc / 4 and large * large * 16 >= 4 * llc
    assert small % 64 == 0 and large % 64 == 0
    # the largest edges that fit, the smallest that exceed: exact where the edge's cube is
    # exactly the budget (a float cube root gave 16 for 32 here: 32768 ** (1/3) < 32)
    assert grid_sizes(4 * MiB, 3, 32, 16) == [32, 96]
    for llc, dims, nbytes, q in [(4 * MiB, 3, 32, 16), (300 * MiB, 2, 16, 64),
                                 (3 * MiB, 3, 16, 16)]:
        small, large = grid_sizes(llc, dims, nbytes, q)
        assert small ** dims * nbytes <= llc / 4 < (small + q) ** dims * nbytes or small == q
        assert (large - q) ** dims * nbytes < 4 * llc <= large ** dims * nbytes


def test_real_state_is_a_pattern():
    u, v = real_state((128, 128), np.float32)
    assert u.dtype == np.float32 and u.std() > 0.01 and np.array_equal(u[:64], u[64:])


def test_peers_named_alike_and_missing_ones_listed():
    assert tuple(PEERS) == PEER_NAMES
    missing = [p for p in PEERS if peer_status(p) and "not installed" in peer_status(p)]
    runnable, skipped = peer_contenders(missing)
    assert not runnable and set(skipped) == set(missing)


@pytest.mark.parametrize(("argv", "words"), [
    (["--dims", "2", "--sizes", "100"], "multiple of 64"),
    (["--dims", "4"], "invalid choice"),
    (["--peers", "nope"], "invalid choice"),
    (["--seconds", "-1"], "positive"),
    (["--dtype", "float16"], "invalid choice"),
    (["--backends", "nosuch"], "nosuch"),
])
def test_bad_options_fail_before_any_work(argv, words, capsys, tmp_path):
    assert main(["bench", "--out", str(tmp_path / "o"), *argv]) == 2
    err = capsys.readouterr().err
    assert "rdgpu: error:" in err and words in err and "triad" not in err


def test_out_must_be_a_folder(capsys, tmp_path):
    f = tmp_path / "file"
    f.write_text("")
    assert main(["bench", "--out", str(f)]) == 2
    assert "--out" in capsys.readouterr().err


@pytest.mark.parametrize("dims", [2, 3])
@pytest.mark.parametrize("name", sorted(PEERS))
def test_each_installed_peer_does_the_same_maths(name, dims):
    """Every peer that can run here agrees with rdgpu's NumPy reference on a small real
    state (the check `rdgpu bench` makes before timing it), float32 and float64 where it
    computes in them.  (The peers come with ``rdgpu[bench]``, not with the tests: where
    one is missing this skips.)"""
    from rdgpu.bench.contenders import check

    why = peer_status(name)
    if why is not None:
        pytest.skip(f"{name}: {why}")
    (peer,), _ = peer_contenders([name])
    for dtype in ("float32", "float64"):
        if peer.lacks(dims, dtype) is None:
            assert check(peer, dims, dtype) is None, (name, dims, dtype)
    # and it leaves the process computing subnormals (Devito's -ffast-math library turned
    # on flush-to-zero in the loading thread: later tests of the worker then failed)
    tiny = np.array([1e-310])
    assert (tiny * 1.0)[0] != 0.0, f"{name} left flush-to-zero on"


def test_rounds_take_the_contenders_in_turn(monkeypatch):
    """Each round times every contender at a size before the next size; a row is its best
    round (a machine drifting over minutes hits every contender alike)."""
    base = next(c for c in rdgpu_contenders(["numpy"]) if c.name == "rdgpu numpy")
    made = []

    def maker(name):
        def make(u, v):
            made.append((name, u.shape[0]))
            return base.make(u, v)
        return make

    pair = [Contender("a", "peer", "0", maker("a")), Contender("b", "peer", "0", maker("b"))]
    monkeypatch.setattr(machine, "_numba_triad", lambda: None)
    opts = Options(backends=[], dims=[2], dtypes=["float32"], sizes={2: [64, 128]},
                   seconds=0.01, rounds=2, triad_max=2 * MiB, triad_seconds=0.001)
    out = run_bench(opts, contenders=pair)
    timed = made[-8:]
    assert timed == [("a", 64), ("b", 64), ("a", 128), ("b", 128)] * 2
    assert all(r["status"] == "ok" and r["mcells"] > 0 for r in out["rows"])
    with pytest.raises(ValueError, match="rounds: expected a whole number"):
        check_options(Options(rounds=0))
