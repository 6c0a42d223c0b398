"""The documentation site (mkdocs.yml, docs/) builds strictly: a broken link or anchor, a
page missing from docs/, a docstring the API reference cannot render fails the build and
this test. Every page of the nav exists, and every public name of rdgpu has an entry in
the reference. A headless Chromium (Debian's ``chromium``, installed by .ci/run) draws the
home page: it must show text and its picture."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import rdgpu

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "mkdocs.yml"


def _nav_pages(node) -> list[str]:
    if isinstance(node, str):
        return [node]
    if isinstance(node, list):
        return [p for item in node for p in _nav_pages(item)]
    if isinstance(node, dict):
        return [p for value in node.values() for p in _nav_pages(value)]
    return []


def _config() -> dict:
    import yaml  # mkdocs depends on PyYAML

    return yaml.safe_load(CONFIG.read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site, built once with ``mkdocs build --strict`` (the ``docs`` extra, part of
    ``test``: a missing mkdocs fails here rather than skipping)."""
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "PYTHONPATH": os.pathsep.join(
        [str(Path(rdgpu.__file__).resolve().parents[1]), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict",
                           "--config-file", str(CONFIG), "--site-dir", str(out)],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, (
        "mkdocs build --strict failed (pip install \".[docs]\" if mkdocs is missing):\n"
        + proc.stderr[-4000:])
    return out


def test_every_nav_page_exists():
    pages = _nav_pages(_config()["nav"])
    assert len(pages) >= 20
    missing = [p for p in pages if not (ROOT / "docs" / p).is_file()]
    assert not missing, f"pages in mkdocs.yml's nav that docs/ lacks: {missing}"


def test_the_site_builds_strictly(site):
    assert (site / "index.html").is_file()
    assert (site / "reference" / "simulation" / "index.html").is_file()


def _reference_ids(site: Path) -> set[str]:
    ids: set[str] = set()
    for page in (site / "reference").rglob("index.html"):
        ids |= set(re.findall(r'id="(rdgpu(?:\.\w+)+|rdgpu)"', page.read_text("utf-8")))
    return ids


def test_every_public_name_has_a_reference_entry(site):
    import rdgpu.analysis
    import rdgpu.pypde
    import rdgpu.surfaces

    ids = _reference_ids(site)
    last = {i.rsplit(".", 1)[-1] for i in ids}
    missing = [f"rdgpu.{n}" for n in rdgpu.__all__ if n not in last]
    for module in (rdgpu.analysis, rdgpu.pypde, rdgpu.surfaces):
        missing += [f"{module.__name__}.{n}" for n in module.__all__
                    if f"{module.__name__}.{n}" not in ids]
    for name in ("rdgpu.simulation.Simulation", "rdgpu.simulation.Result",
                 "rdgpu.models.define_model", "rdgpu.domains.Grid",
                 "rdgpu.domains.mesh.SurfaceMesh", "rdgpu.runs.sweep.sweep"):
        if name not in ids:
            missing.append(name)
    assert not missing, f"public names without an API reference entry: {missing}"


def test_the_cli_reference_is_the_parsers_help(site):
    html = (site / "reference" / "cli" / "index.html").read_text("utf-8")
    assert "usage: rdgpu run" in html and "--checkpoint" in html and "rdgpu-help" not in html


def _chromium() -> str | None:
    return next((p for p in map(shutil.which, ("chromium", "chromium-browser")) if p), None)


@pytest.mark.skipif(_chromium() is None,
                    reason="no chromium binary (Debian: apt-get install chromium; .ci/run "
                           "installs it)")
def test_home_page_screenshot_shows_text_and_picture(site, tmp_path):
    """Headless Chromium renders the built home page: not blank, and its picture loaded
    (a missing image would leave the area of the Gray-Scott picture white)."""
    np = pytest.importorskip("numpy")
    iio = pytest.importorskip("imageio.v3")
    shot = tmp_path / "home.png"
    proc = subprocess.run(
        [_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
         "--window-size=1280,1600", f"--screenshot={shot}",
         (site / "index.html").as_uri()],
        capture_output=True, text=True, timeout=120)
    assert shot.is_file(), f"chromium wrote no screenshot:\n{proc.stderr[-2000:]}"
    img = iio.imread(shot)[..., :3].astype(np.int16)
    assert img.std() > 10, "the home page rendered blank"
    # the picture: the Gray-Scott labyrinth has its own colours, none of the theme's
    picture = iio.imread(ROOT / "docs" / "gallery" / "gs-seed001-stripes.png")[..., :3]
    colours = {tuple(c) for c in picture.reshape(-1, 3)[::97]}
    page = {tuple(c) for c in img.reshape(-1, 3)[::7]}
    assert len(colours & page) >= 5, "the home page's picture did not load"


def test_every_reference_callable_documents_its_arguments():
    """numpydoc (docs/architecture.md, "Docstrings"): every callable the API reference shows
    names each of its arguments in a ``Parameters`` section (a dataclass's fields may be
    ``Attributes``): `tests.docstring_audit`."""
    from tests.docstring_audit import gaps

    found = gaps()
    assert not found, "arguments without a Parameters entry:\n" + "\n".join(
        f"{where}: {qual}: {', '.join(missing)}" for qual, where, missing in found)
