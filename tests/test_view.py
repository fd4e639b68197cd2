"""pymr view (issue 33): the run's HTML page, offline, checked in numbers and in a browser.

Independent expectations: the solids' volumes against the box's and the 12-gon prism's
formulas (divergence theorem over the drawn triangles); the flexible barrel's tube centred
on the deformed centre line of pymr.geometry, and at its end on the muzzle marker the run
wrote; the columns and units chosen by the results' JSON; each frame's time line at the
frame's time. In headless chromium (Debian's, through selenium): the 3-D canvas holds the
mechanism (pixels that change when its traces are hidden), the slider moves the view and
the columns' time line, and a screenshot is kept (PYMR_TEST_ARTEFACTS, else pytest's
tmp_path)."""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr import view
from pymr.plot import PlotError

ROOT = Path(__file__).resolve().parents[1]
TANK = ROOT / "input" / "tank_gun_turret.nml"
BROWSER, DRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"


@pytest.fixture(scope="module")
def tank(tmp_path_factory):
    """A short tank run (0.3 s, a row every 2 ms) with its energy columns."""
    out = tmp_path_factory.mktemp("view") / "tank.csv"
    pymr.run(TANK, out, overrides={"scene.t_end": 0.3, "output.dt": 0.002,
                                   "output.quantities": ["coordinates", "markers", "energy"]})
    return pymr.load_results(out)


def motion_of(res, **options):
    """The motion to draw, as pymr view takes it (pymr.geometry)."""
    from pymr.geometry import motion
    return motion(res, **options)


def figure_json(page: str) -> tuple[list[dict], dict, list[dict]]:
    """The figure a page holds: its traces, layout and frames, as the page gives them to
    Plotly.newPlot and Plotly.addFrames (JSON)."""
    decode = json.JSONDecoder().raw_decode
    at = page.index('"pymr-view",', page.index("Plotly.newPlot(")) + len('"pymr-view",')
    data, at = decode(page, len(page[:at]) + len(page[at:]) - len(page[at:].lstrip()))
    at = page.index(",", at) + 1
    layout, _ = decode(page, at + len(page[at:]) - len(page[at:].lstrip()))
    at = page.index("'pymr-view',", page.index("Plotly.addFrames(")) + len("'pymr-view',")
    frames, _ = decode(page, at + len(page[at:]) - len(page[at:].lstrip()))
    return data, layout, frames


def values(v) -> np.ndarray:
    """A trace's array as plotly writes it: a list, or {"dtype", "bdata"} (base64)."""
    import base64
    if isinstance(v, dict):
        return np.frombuffer(base64.b64decode(v["bdata"]), dtype=v["dtype"]).astype(float)
    return np.asarray(v, dtype=float)


def signed_volume(points: np.ndarray, faces: np.ndarray) -> float:
    """The volume a closed triangle mesh encloses (divergence theorem), signed by its faces' order."""
    a, b, c = (points[faces[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


# ------------------------------------------------------------------ numbers

def test_solids_enclose_the_volumes_of_their_shapes():
    """A box of 0.3 x 0.5 x 0.7 m turned and moved encloses 0.105 m^3; a cylinder of length
    2 and radius 0.1 the 12-gon prism's 6 r^2 sin(30 deg) L = 0.06 m^3; a straight tube of
    the same length and radius the same; every ring point of a bent tube lies at the radius
    from its centre point, across the line."""
    from pymr.geometry import BodyTrack
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    body = BodyTrack(name="b", kind="rigid", origin=np.array([[5.0, 1.0, 2.0]]), rotation=rot[None], shape="box",
                     size=np.array([0.3, 0.5, 0.7]), centre=np.array([1.0, 0, 0]), line=None, displacement=None)
    points, faces = view.body_solid(body)
    assert abs(signed_volume(points[0], faces)) == pytest.approx(0.105, rel=1e-12)
    assert points[0].mean(axis=0) == pytest.approx([5.0, 2.0, 2.0], abs=1e-12)      # origin + R centre
    body.shape, body.size, body.centre = "cylinder", np.array([2.0, 0.1, 0.0]), np.zeros(3)
    points, faces = view.body_solid(body)
    prism = 6 * 0.1 ** 2 * np.sin(np.pi / 6) * 2.0
    assert abs(signed_volume(points[0], faces)) == pytest.approx(prism, rel=1e-12)
    body.kind, body.line = "beam", np.stack([np.linspace(0, 2.0, 9), np.zeros(9), np.zeros(9)], axis=1)[None]
    points, faces = view.body_solid(body)
    assert abs(signed_volume(points[0], faces)) == pytest.approx(prism, rel=1e-12)
    s = np.linspace(0, 1.5, 30)
    bent = np.stack([np.cos(s), np.sin(s), 0.2 * s], axis=1)[None]
    rings = view.tube_points(bent, 0.05).reshape(30, view.SIDES, 3)
    offset = rings - bent[0][:, None, :]
    assert np.linalg.norm(offset, axis=2) == pytest.approx(0.05, rel=1e-12)
    tangent = np.gradient(bent[0], axis=0)
    assert np.abs(np.einsum("psi,pi->ps", offset, tangent / np.linalg.norm(tangent, axis=1)[:, None])).max() < 1e-12


def test_columns_are_chosen_by_the_results_metadata(tank):
    """Default: the muzzle's position; 'energy.*' gives the JSON's energy group, in one panel
    per unit (J); patterns and names in the order given; units on the axes from the JSON."""
    info = tank.column_info
    assert view.select_columns(tank) == [c.name for c in info if c.owner == "muzzle" and c.quantity == "position"]
    energy = [c.name for c in info if c.group == "energy"]
    assert len(energy) >= 5 and view.select_columns(tank, ["energy.*"]) == energy
    [(title, cols)] = view.panels(tank, energy)
    assert cols == energy and title.endswith("(J)")
    both = view.select_columns(tank, ["gun.a[12]", "elevation.q", "gun.a1"])
    assert both == ["gun.a1", "gun.a2", "elevation.q"]                   # as asked, each once
    units = {c.name: c.unit for c in info}
    chosen = view.panels(tank, both)
    assert [cols for _, cols in chosen] == [["gun.a1", "gun.a2"], ["elevation.q"]]      # by unit
    assert [title.endswith(f"({units[cols[0]]})") for title, cols in chosen] == [True, True]
    with pytest.raises(PlotError, match="no column matches 'nothing.\\*'"):
        view.select_columns(tank, ["nothing.*"])


def test_page_is_offline_and_draws_the_geometry(tank, tmp_path):
    """The page embeds plotly.js and fetches nothing (no http(s) script); it has one frame
    per chosen row (the first, the last, evenly spread), the tube of the barrel centred on
    the deformed centre line of pymr.geometry in every frame, the line's end on the muzzle
    the run wrote (at deflections x1), and each panel's time line at its frame's time."""
    out = view.view(tank, tmp_path / "v.html", frames=7, columns=["muzzle.y", "energy.*"])
    page = out.read_text()
    assert not re.search(r"<script[^>]*\bsrc\s*=\s*[\"']?https?:", page, re.I)
    assert "plotly.js v" in page and len(page) > 3e6          # the library itself, inline
    assert not list(tmp_path.glob("*.tmp"))
    data, layout, frames = figure_json(page)
    motion = motion_of(tank, frames=7)
    assert len(frames) == 7 and len(layout["sliders"][0]["steps"]) == 7
    assert motion.t[0] == tank.t[0] and motion.t[-1] == tank.t[-1]
    gun = next(b for b in motion.bodies if b.line is not None)
    sides, n = view.SIDES, gun.line.shape[1]
    muzzle = tank.marker("muzzle")[0][np.searchsorted(tank.t, motion.t)]
    follow = [i for i, tr in enumerate(data) if tr.get("name") == "time shown"]
    assert len(follow) == 2                                   # muzzle.y (m), the energies (J)
    titles = [layout[f"yaxis{'' if i == 1 else i}"]["title"]["text"] for i in (1, 2)]
    assert titles[0].endswith("(m)") and titles[1].endswith("(J)")
    for k, frame in enumerate(frames):
        mesh = frame["data"][0]
        pts = np.column_stack([values(mesh[a]) for a in "xyz"])
        centres = _tube_centres(pts, n, sides, gun.line[k])
        assert np.abs(centres - gun.line[k]).max() < 1e-6 * np.abs(gun.line).max()   # float32 in the page
        assert np.abs(gun.line[k, -1] - muzzle[k]).max() < 1e-9
        times = [values(frame["data"][frame["traces"].index(i)]["x"]) for i in follow]
        assert np.array(times) == pytest.approx(motion.t[k], abs=1e-12)


def test_every_and_frames_choose_the_rows(tank, tmp_path):
    """--every 5: the panels hold rows 0, 5, 10 ... and the frames are those rows (all of
    them when --frames allows: 31 of the 151); with --frames 4 as well, 4 of them, the
    first and the last included."""
    for frames, count in ((1000, 31), (4, 4)):
        page = view.view(tank, tmp_path / "v.html", every=5, frames=frames).read_text()
        data, layout, found = figure_json(page)
        panel = next(tr for tr in data if tr.get("name") == "muzzle.x")
        assert values(panel["x"]).tolist() == tank.t[::5].tolist()
        times = [values(f["data"][-1]["x"])[0] for f in found]
        assert len(found) == count and set(times) <= set(tank.t[::5].tolist())
        assert times[0] == tank.t[0] and times[-1] == tank.t[::5][-1]


def _tube_centres(points: np.ndarray, n: int, sides: int, line: np.ndarray) -> np.ndarray:
    """The centres of the n rings (of `sides` points) of the tube among a mesh's points: the
    run of n * sides points whose ring centres lie nearest `line`."""
    for start in range(0, len(points) - n * sides + 1):
        centres = points[start:start + n * sides].reshape(n, sides, 3).mean(axis=1)
        if np.abs(centres[0] - line[0]).max() < 1e-3:
            return centres
    raise AssertionError("no tube along the flexible body's line in the mesh")


def test_bad_options_are_one_line_exit_1(tank, tmp_path, capsys):
    """An unknown column, a bad scale, a page that is not .html, a results file that is not
    there: one line naming it, exit 1, no traceback, and no page written."""
    from pymr.cli import main
    cases = [(["--column", "nothing.*"], "no column matches 'nothing.*'"),
             (["--column", "muzzle.y", ""], "pymr: error: --column: an empty name\n"),   # was 'columns[1]: ...'
             (["--exaggerate", "-2"], "exaggerate: a scale of the deflections, a finite number from 0"),
             (["--exaggerate", "nan"], "(0 draws the bodies undeformed), got nan"),
             (["--frames", "0"], "--frames: '0': a whole number of frames"),
             (["-o", str(tmp_path / "v.png")], ".png is not a format of the view")]
    for args, words in cases:
        output = [] if "-o" in args else ["-o", str(tmp_path / "v.html")]
        assert main(["view", tank.path, *output, *args]) == 1
        err = capsys.readouterr().err
        assert words in err and len(err.splitlines()) == 1, err
    r = subprocess.run(["pymr", "view", str(tmp_path / "none.csv")], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and "no such result file" in r.stderr and len(r.stderr.splitlines()) == 1
    assert not list(tmp_path.iterdir())


# ------------------------------------------------------------------ in a browser

def chromium():
    """Debian's chromium, headless, through selenium. Missing, the test FAILS (CI installs
    it: .ci/setup). WebGL is software-drawn (SwiftShader): no GPU on a test machine."""
    missing = [p for p in (BROWSER, DRIVER) if not os.access(p, os.X_OK)]
    if missing:
        pytest.fail(f"{' and '.join(missing)} not found: the view's browser test needs Debian's chromium and "
                    "chromium-driver (apt-get install chromium chromium-driver, as .ci/setup does)")
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        pytest.fail("selenium is not installed: the view's browser test needs it (pip install selenium, as "
                    ".ci/setup does)")
    options = webdriver.ChromeOptions()
    options.binary_location = BROWSER
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
                 "--enable-unsafe-swiftshader", "--window-size=1400,1000", "--force-device-scale-factor=1",
                 "--disable-dev-shm-usage"):
        options.add_argument(flag)
    return webdriver.Chrome(options=options, service=Service(DRIVER))


def wait_for(driver, script: str, what: str, timeout: float = 30.0):
    """Poll `script` in the page until it returns something true; fail naming `what`."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = driver.execute_script(script)
        if value:
            return value
        time.sleep(0.05)
    pytest.fail(f"the page did not {what} within {timeout:g} s")


GD = "var gd = document.getElementById('pymr-view');"


def open_page(driver, page: Path, frames: int) -> None:
    """Load the page from the disk and wait until plotly has drawn it, its frames added."""
    driver.get(page.resolve().as_uri())
    if not driver.execute_script("var c = document.createElement('canvas'); return !!c.getContext('webgl');"):
        pytest.fail("headless chromium gives no WebGL context (SwiftShader): the 3-D view cannot be drawn")
    wait_for(driver, GD + "return gd && gd._fullLayout && gd._fullLayout.scene && gd._fullLayout.scene._scene && "
             f"gd._transitionData && gd._transitionData._frames.length === {frames} && "
             "gd.querySelector('.gl-container canvas') !== null;", "draw its 3-D scene and add its frames")
    time.sleep(0.3)          # the WebGL frame after the last layout


def canvas_pixels(driver) -> np.ndarray:
    """The 3-D canvas as the browser shows it (RGB array), from a screenshot of the element."""
    import io
    from PIL import Image
    from selenium.webdriver.common.by import By
    element = driver.find_element(By.CSS_SELECTOR, "#pymr-view .gl-container canvas")
    return np.asarray(Image.open(io.BytesIO(element.screenshot_as_png)).convert("RGB"), dtype=int)


def changed(a: np.ndarray, b: np.ndarray) -> float:
    """The fraction of pixels that differ between two pictures of the same size."""
    return float((np.abs(a - b).sum(axis=2) > 24).mean())


def mechanism_drawn(driver) -> float:
    """The fraction of the 3-D canvas the mechanism covers: the pixels that change when its
    traces (every 3-D trace) are hidden, then shown again."""
    shown = canvas_pixels(driver)
    hide = GD + ("var k = []; gd.data.forEach(function(t, i) { if (t.type !== 'scatter') k.push(i); });"
                 "Plotly.restyle(gd, {visible: arguments[0]}, k);")
    driver.execute_script(hide, False)
    time.sleep(0.3)
    bare = canvas_pixels(driver)
    driver.execute_script(hide, True)
    time.sleep(0.3)
    return changed(shown, bare)


def click_slider(driver, fraction: float) -> int:
    """Click the slider's rail at `fraction` of its length; the active step it moved to."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    rail = driver.find_element(By.CSS_SELECTOR, "#pymr-view .slider-container .slider-rail-touch-rect")
    width = rail.size["width"]
    ActionChains(driver).move_to_element_with_offset(rail, int((fraction - 0.5) * width), 0).click().perform()
    return wait_for(driver, GD + "var a = gd._fullLayout.sliders[0].active; return a > 0 ? a : 0;",
                    "move its slider")


def follow_lines(driver) -> list[list[float]]:
    """The x of each column panel's time line as the page holds it now."""
    return driver.execute_script(GD + "return gd.data.filter(function(t) { return t.name === 'time shown'; })"
                                 ".map(function(t) { return Array.from(t.x); });")


def play_to_the_end(driver, step: int, frames: int, last: float) -> None:
    """'play' shows the frames on from `step` to the last, and moves the time lines to its
    time. (Pause is plotly's own button; a software-drawn page is too busy while it plays
    to be stopped at a moment a test could rely on.)"""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    play = driver.find_elements(By.CSS_SELECTOR, "#pymr-view .updatemenu-button")[0]
    assert play.text == "play"
    ActionChains(driver).move_to_element(play).click().perform()
    # the frame shown, not the slider's active step: after a click on its rail the slider
    # at times stays where it was while the frames play on (plotly; 3 runs in 8 here)
    wait_for(driver, GD + f"return gd._fullLayout._currentFrame === '{frames - 1}';", "play to its last frame")
    wait_for(driver, GD + f"return gd.data.filter(function(t) {{ return t.name === 'time shown'; }})"
             f".every(function(t) {{ return t.x[0] === {float(last)!r}; }});", "move its time lines to the end")


def artefacts(tmp_path: Path) -> Path:
    """Where a test keeps its pictures: PYMR_TEST_ARTEFACTS, else pytest's tmp_path."""
    folder = Path(os.environ.get("PYMR_TEST_ARTEFACTS") or tmp_path)
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def test_view_in_headless_chromium(tank, tmp_path):
    """The tank's page in headless chromium, from the disk (file://): plotly draws the 3-D
    scene, the mechanism covers part of the canvas; a click at 3/4 of the slider makes a
    later step active, moves the mechanism (the canvas changes) and each column panel's
    time line to that frame's time; the screenshot is kept; play goes on to the end."""
    frames = 20
    columns = ["muzzle.y", "energy.kinetic", "energy.drive_work"]
    page = view.view(tank, tmp_path / "tank.html", frames=frames, exaggerate=50.0, columns=columns)
    lines = len(view.panels(tank, columns))                       # m and J: 2 panels, a time line each
    times = motion_of(tank, frames=frames).t
    driver = chromium()
    try:
        open_page(driver, page, frames)
        assert driver.execute_script(GD + "return gd._fullLayout.sliders[0].active;") == 0
        assert lines == 2 and follow_lines(driver) == [[times[0]] * 2] * lines
        drawn = mechanism_drawn(driver)
        assert drawn > 0.005, f"the mechanism covers {drawn:.2%} of the 3-D canvas: nothing drawn"
        before = canvas_pixels(driver)
        step = click_slider(driver, 0.75)
        assert abs(step - 0.75 * (frames - 1)) <= 2
        wait_for(driver, GD + f"return gd.data.filter(function(t) {{ return t.name === 'time shown'; }})"
                 f".every(function(t) {{ return t.x[0] === {float(times[step])!r}; }});", "move its time lines")
        assert follow_lines(driver) == [[times[step]] * 2] * lines
        time.sleep(0.3)
        moved = changed(before, canvas_pixels(driver))
        assert moved > 0.001, f"the 3-D canvas did not change when the slider moved ({moved:.3%} of its pixels)"
        shot = artefacts(tmp_path) / "view_tank.png"
        driver.save_screenshot(str(shot))
        print(f"screenshot of the view: {shot}")
        assert shot.stat().st_size > 10000
        play_to_the_end(driver, step, frames, times[-1])
    finally:
        driver.quit()


def docs_picture(path: Path, columns=("muzzle.y", "gun.a1", "gun.a2", "energy.drive_work"), at: float = 0.68) -> None:
    """docs/view.png by the browser test's code path: the tank's whole run (1 s), its page
    (deflections x50, the default 100 frames), the slider clicked at `at` of its length.
    ``python tests/test_view.py docs/view.png`` (from the checkout, the package installed)."""
    import tempfile
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "tank.csv"
        pymr.run(TANK, out, overrides={"output.quantities": ["coordinates", "markers", "energy"]})
        page = view.view(out, Path(folder) / "tank.html", exaggerate=50.0, columns=list(columns))
        print(f"{page.stat().st_size / 1e6:.2f} MB page")
        driver = chromium()
        try:
            open_page(driver, page, 100)
            click_slider(driver, at)
            time.sleep(1.0)
            shot = Path(folder) / "view.png"
            driver.save_screenshot(str(shot))
            os.replace(shot, path) if Path(folder).stat().st_dev == Path(path).resolve().parent.stat().st_dev \
                else shutil.move(shot, path)
        finally:
            driver.quit()


if __name__ == "__main__":
    import sys
    pytest.fail = lambda message: sys.exit(f"test_view: {message}")       # outside pytest: one line
    docs_picture(Path(sys.argv[1]))
