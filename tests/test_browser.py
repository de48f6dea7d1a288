"""What a person sees in JupyterLab: a real JupyterLab server and headless Chromium driven
by WebDriver (selenium). Skipped with a reason where no browser is installed (Debian:
``apt-get install chromium chromium-driver``) or selenium is missing (the ``dev`` extra).

The server binds to 127.0.0.1 on a free port, with a token, in a temporary root that
holds a copy of notebook 03 (opened to check that it does not open as modified) and a
small notebook that builds the crossover widget of notebook 03 on a tiny model (seconds
of training). The test runs it, changes a control as a person would and checks that the
view redraws: the status line passes through "drawing..." with the controls disabled,
then shows the new title; the picture changes; nothing reports an error.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from io import BytesIO
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
NOTEBOOKS = Path(__file__).resolve().parents[1] / "notebooks"

if not (CHROMIUM.exists() and CHROMEDRIVER.exists()):
    pytest.skip(
        f"no browser: {CHROMIUM} and {CHROMEDRIVER} are needed (Debian: apt-get install "
        "chromium chromium-driver)",
        allow_module_level=True,
    )
pytest.importorskip("selenium", reason="selenium is not installed (the dev extra)")
pytest.importorskip("jupyterlab", reason="jupyterlab is not installed (the notebooks extra)")

from selenium import webdriver  # noqa: E402
from selenium.common.exceptions import TimeoutException  # noqa: E402
from selenium.webdriver.chrome.service import Service  # noqa: E402
from selenium.webdriver.common.action_chains import ActionChains  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402
from selenium.webdriver.common.keys import Keys  # noqa: E402
from selenium.webdriver.support.ui import Select, WebDriverWait  # noqa: E402

pytestmark = pytest.mark.slow
HERE = ".jp-NotebookPanel:not(.lm-mod-hidden)"  # the notebook shown, not one behind it

# The small notebook: a tiny model (two iterations per block), then the widget cell of
# notebook 03 as it stands there.
SETUP = """\
import torch
from mrlib import viz
from mrlib.datasets.synthetic import synthetic_walk, synthetic_wave
from mrlib.model.config import ModelConfig, TrainConfig
from mrlib.model.trained import load_model
from mrlib.representation.body import load_body_model
from mrlib.training.data import TrainingSet
from mrlib.training.trainer import train

torch.set_num_threads(1)
body = load_body_model()
clips = [synthetic_walk("walk_sad", seconds=4.0, fps=10.0, body=body),
         synthetic_wave(seconds=3.6, fps=10.0, body=body)]
cfg = TrainConfig(model=ModelConfig(num_levels=4, gen_hidden=(24, 24), disc_hidden=(24, 24)),
                  block_iterations=(2, 2), n_critic=1, checkpoint_every=0)
model = load_model(train(TrainingSet.from_motions(clips), cfg, "run", body=body,
                         progress=False).checkpoint)
"""
WIDGET = """\
box, update = viz.interactive_crossover(model, body, frames=3, window=10)
display(box)
view = update()
"""

# A walk in the live 3D player (trame), forced live: the server's kernel has the static
# backend, as the notebooks under test have.
PLAYER = """\
from mrlib.datasets.synthetic import synthetic_walk
from mrlib.representation.body import load_body_model
from mrlib.viz import play_motion

body = load_body_model()
walk = synthetic_walk("walk_happy", seconds=2.0, fps=30.0, body=body)
player = play_motion(walk, body, live=True)
player
"""

# Records every text the status line shows, with whether the controls were disabled then.
WATCH_STATUS = """
const status = document.querySelector('.mrlib-status');
window.mrlibSeen = [];
const note = () => window.mrlibSeen.push([status.innerText.trim(),
    Array.from(document.querySelectorAll('.jupyter-widgets select')).every(s => s.disabled)]);
new MutationObserver(note).observe(status, {subtree: true, childList: true, characterData: true});
"""


def _notebook(cells: list[str], metadata: dict) -> dict:
    code = [{"cell_type": "code", "execution_count": None, "id": f"cell{k}", "metadata": {},
             "outputs": [], "source": src} for k, src in enumerate(cells)]  # fmt: skip
    return {"cells": code, "metadata": metadata, "nbformat": 4, "nbformat_minor": 5}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """``(base_url, token, log)`` of a JupyterLab server on 127.0.0.1."""
    tmp = tmp_path_factory.mktemp("lab")
    root = tmp / "root"
    root.mkdir()
    shutil.copy(NOTEBOOKS / "03_condition_crossover.ipynb", root / "03.ipynb")
    meta = json.loads((NOTEBOOKS / "03_condition_crossover.ipynb").read_text())["metadata"]
    (root / "widget.ipynb").write_text(json.dumps(_notebook([SETUP, WIDGET], meta), indent=1))
    (root / "player.ipynb").write_text(json.dumps(_notebook([PLAYER], meta), indent=1))
    port, token = _free_port(), secrets.token_hex(16)
    env = dict(os.environ, JUPYTER_CONFIG_DIR=str(tmp / "config"),
               JUPYTER_RUNTIME_DIR=str(tmp / "runtime"), IPYTHONDIR=str(tmp / "ipython"),
               JUPYTERLAB_SETTINGS_DIR=str(tmp / "settings"),
               JUPYTERLAB_WORKSPACES_DIR=str(tmp / "workspaces"),
               PYVISTA_OFF_SCREEN="true", PYVISTA_JUPYTER_BACKEND="static",
               VTK_DEFAULT_OPENGL_WINDOW="vtkEGLRenderWindow")  # fmt: skip
    log_path = tmp / "server.log"
    log = log_path.open("w")
    server = subprocess.Popen(
        [sys.executable, "-m", "jupyterlab", "--no-browser", "--ServerApp.ip=127.0.0.1",
         f"--ServerApp.port={port}", "--ServerApp.port_retries=0",
         f"--IdentityProvider.token={token}", f"--ServerApp.root_dir={root}",
         "--LabApp.news_url=None",
         "--LabApp.check_for_updates_class=jupyterlab.NeverCheckForUpdate",
         *(["--allow-root"] if os.name == "posix" and os.geteuid() == 0 else [])],
        stdout=log, stderr=subprocess.STDOUT, env=env, cwd=root,
    )  # fmt: skip
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                with urllib.request.urlopen(f"{base}/api/status?token={token}", timeout=2):
                    break
            except OSError:
                if server.poll() is not None or time.monotonic() > deadline:
                    pytest.fail(f"JupyterLab did not start:\n{log_path.read_text()[-3000:]}")
                time.sleep(0.5)
        yield base, token, log_path
    finally:
        server.terminate()
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()
        log.close()


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    profile = tmp_path_factory.mktemp("chromium")
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync",
                 "--disable-dev-shm-usage", "--window-size=1400,1800",
                 f"--user-data-dir={profile}"):  # fmt: skip
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    driver.set_page_load_timeout(60)
    yield driver
    driver.quit()


def _open(driver, lab, name: str) -> None:
    """Open a notebook and wait until its kernel is idle. On a busy machine JupyterLab
    may ask for the kernel (its list of kernels came late): the preselected one, the
    notebook's own, is accepted."""
    base, token, _ = lab
    driver.get(f"{base}/lab/tree/{name}?reset&token={token}")  # only this one open
    wait = WebDriverWait(driver, 180, poll_frequency=0.5)
    wait.until(lambda d: d.find_elements(By.CSS_SELECTOR, HERE + " .jp-Notebook .jp-Cell"))

    def ready(d) -> bool:
        for button in d.find_elements(By.CSS_SELECTOR, ".jp-Dialog .jp-mod-accept"):
            button.click()
            return False
        return d.execute_script(
            "const s = document.querySelector('.jp-Notebook-ExecutionIndicator');"
            "return s !== null && s.getAttribute('data-status') === 'idle';"
        )

    wait.until(ready)


def _menu(driver, menu: str, command: str) -> None:
    """Click ``menu`` in the menu bar, then its item for ``command``."""
    label = next(m for m in driver.find_elements(By.CSS_SELECTOR, ".lm-MenuBar-itemLabel")
                 if m.text == menu)  # fmt: skip
    label.click()
    item = WebDriverWait(driver, 10).until(
        lambda d: d.find_element(By.CSS_SELECTOR, f"li[data-command='{command}']")
    )
    item.click()


def _run_all(driver) -> None:
    """Run every cell (Run > Run All Cells), again if the first click went nowhere."""
    for _ in range(3):
        _menu(driver, "Run", "runmenu:run-all")
        try:
            WebDriverWait(driver, 10).until(lambda d: any(
                p.text.strip() not in ("", "[ ]:")
                for p in d.find_elements(By.CSS_SELECTOR, HERE + " .jp-CodeCell .jp-InputPrompt")))  # fmt: skip
            return
        except TimeoutException:
            continue
    pytest.fail("Run All Cells did not start the notebook")


def _status(driver) -> str:
    found = driver.find_elements(By.CSS_SELECTOR, HERE + " .mrlib-status")
    return found[0].text.strip() if found else ""


def _picture(driver) -> str:
    """The ``src`` of the widget's figure (a data URL), "" before it is drawn."""
    found = driver.find_elements(By.CSS_SELECTOR, HERE + " .jupyter-widgets .jp-OutputArea img")
    return found[0].get_attribute("src") if found else ""


def _errors(driver, lab) -> list[str]:
    """Tracebacks in the page, errors in the browser console and the server log."""
    seen = [e.text for e in driver.find_elements(By.CSS_SELECTOR, HERE + " .jp-OutputArea-output")
            if "Traceback" in e.text or "Error" in e.text]  # fmt: skip
    seen += [e["message"] for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    server_log = lab[2].read_text()
    seen += [ln for ln in server_log.splitlines() if ln.startswith("[E") or "Traceback" in ln]
    return seen


def test_notebook_03_keeps_its_kernelspec(lab, browser):
    """Its kernelspec is the one ``make env`` installs (``python3``, "Python 3 (mrlib)"),
    so JupyterLab has nothing to rewrite there when the kernel starts: saved straight
    after opening, the notebook comes back with the same kernelspec and cells. (The
    ``language_info`` JupyterLab writes names the kernel's exact Python version, which
    differs between machines; a notebook that does not carry it opens modified.)"""
    root = lab[2].parent / "root"
    path = root / "03.ipynb"
    before, stamp = json.loads(path.read_text()), path.stat().st_mtime_ns
    _open(browser, lab, "03.ipynb")
    time.sleep(2)  # the kernel's info has arrived and been applied
    _menu(browser, "File", "docmanager:save")

    def saved(_):  # written anew and complete (the server writes the file in place)
        if path.stat().st_mtime_ns == stamp:
            return None
        try:
            return json.loads(path.read_text())
        except ValueError:
            return None

    after = WebDriverWait(browser, 60, poll_frequency=0.5).until(saved)
    assert after["metadata"]["kernelspec"] == before["metadata"]["kernelspec"]
    assert [c["source"] for c in after["cells"]] == [c["source"] for c in before["cells"]]
    changed = {k for k, v in after["metadata"].items() if before["metadata"].get(k) != v}
    assert changed <= {"language_info"}, changed


def test_crossover_widget_redraws_in_the_browser(lab, browser):
    _open(browser, lab, "widget.ipynb")
    _run_all(browser)
    wait = WebDriverWait(browser, 150, poll_frequency=0.5)
    wait.until(lambda d: "nearest-window labels" in _status(d))
    first, picture = _status(browser), _picture(browser)
    assert first.startswith("coarse 'walk_sad' at levels 1-2, fine 'wave' at levels 3-4")
    assert picture.startswith("data:image/png")
    browser.execute_script(WATCH_STATUS)
    # the coarse label as the fine one: one label at every level
    coarse = Select(browser.find_elements(By.CSS_SELECTOR, HERE + " .jupyter-widgets select")[0])
    coarse.select_by_visible_text("wave")
    wait.until(lambda d: "at every level" in _status(d))
    seen = browser.execute_script("return window.mrlibSeen;")
    busy = [disabled for text, disabled in seen if text.startswith("drawing")]
    assert busy and all(busy), seen  # drawing..., with the controls disabled
    assert _status(browser).startswith("'wave' at every level (seed 0)")
    assert _picture(browser) not in ("", picture)
    selects = browser.find_elements(By.CSS_SELECTOR, HERE + " .jupyter-widgets select")
    assert not any(s.get_attribute("disabled") for s in selects)  # enabled again
    assert not _errors(browser, lab)


def _pixels(element) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(BytesIO(element.screenshot_as_png)).convert("RGB"), float)


def test_motion_player_plays_and_rotates_in_jupyterlab(lab, browser):
    """``play_motion`` in a live JupyterLab: the body drawn through trame in an iframe;
    the frame slider poses it anew, dragging the view turns it; no error anywhere."""
    _open(browser, lab, "player.ipynb")
    _run_all(browser)
    view = WebDriverWait(browser, 180).until(
        lambda d: d.find_element(By.CSS_SELECTOR, HERE + " .jp-OutputArea iframe")
    )
    time.sleep(8)  # the page in the iframe loads and draws the scene
    still = _pixels(view)
    skin = (np.abs(still - [212, 178, 148]).sum(-1) < 90).sum()
    assert skin > 2000, "no body in the 3D view"
    handle = browser.find_element(By.CSS_SELECTOR, HERE + " .jp-OutputArea .noUi-handle")
    handle.click()
    for _ in range(20):
        handle.send_keys(Keys.ARROW_RIGHT)
    WebDriverWait(browser, 60).until(
        lambda d: (
            "0.67 s of 2.00 s" in d.find_element(By.CSS_SELECTOR, HERE + " .jp-OutputArea").text
        )
    )
    time.sleep(3)
    posed = _pixels(view)
    assert np.abs(posed - still).mean() > 1.0, "the frame slider left the view as it was"
    ActionChains(browser).move_to_element(view).click_and_hold().move_by_offset(120, 0).release(
    ).perform()  # fmt: skip
    time.sleep(3)
    turned = _pixels(view)
    assert np.abs(turned - posed).mean() > 1.0, "dragging did not turn the view"
    assert not _errors(browser, lab)
    assert "ERR|" not in lab[2].read_text()  # VTK's errors, in the kernel's output
