"""The documentation site builds with --strict and renders in a browser: the start page and the API reference.

The site is built from the working tree into a temporary folder, served on 127.0.0.1 and opened in
headless Chromium (`make test` installs the Debian package where it is missing). What the tests look
for exists only once each part has worked: the API reference's entries are written by mkdocstrings from
the docstrings, the `js-focus-visible` class by the theme's JavaScript in the browser, and the header's
colour by the theme's stylesheet.
"""

import functools
import http.server
import os
import re
import shutil
import subprocess
import sys
import threading
import urllib.request
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
MATERIAL_INDIGO = (0x40, 0x51, 0xB5)
"""The Material theme's default primary colour, the header bar's."""

pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="no chromium: `make browser` installs it (Debian, as root)")


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """The URL of the site built from the working tree with --strict, served on 127.0.0.1."""
    pytest.importorskip("mkdocs", reason="mkdocs is a test extra: pip install -e '.[test]'")
    folder = tmp_path_factory.mktemp("site")
    built = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(folder)], cwd=ROOT,
                           capture_output=True, text=True, timeout=600, env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert built.returncode == 0, built.stderr[-3000:]
    handler = functools.partial(QuietHandler, directory=str(folder))
    with http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler) as server:
        thread = threading.Thread(target=server.serve_forever, daemon=True)
        thread.start()
        yield f"http://127.0.0.1:{server.server_address[1]}"
        server.shutdown()


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format, *args):
        pass


def chromium(*args: str) -> subprocess.CompletedProcess:
    # --no-sandbox: Chromium's sandbox refuses to run as root, which `make test` on a fresh machine is
    return subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                           "--virtual-time-budget=5000", *args], capture_output=True, text=True, timeout=120)


def rendered(url: str) -> str:
    """The page's DOM after the browser has run its scripts."""
    done = chromium("--dump-dom", url)
    assert done.returncode == 0 and "</html>" in done.stdout, done.stderr[-2000:]
    return done.stdout


def text_of(dom: str) -> str:
    return " ".join(re.sub(r"<[^>]+>", " ", dom).split())


def test_the_start_page_renders_with_the_theme_and_its_pictures(site, tmp_path):
    dom = rendered(f"{site}/index.html")
    assert re.search(r'<html[^>]*class="[^"]*js-focus-visible', dom), "the theme's JavaScript did not run"
    assert re.search(r'<h1 id="lava-bridge-mj">lava-bridge-mj', dom)
    text = text_of(dom)
    assert "which start-state distribution makes online RL learn fastest and most robustly?" in text
    for page in ("The environment and its tasks", "Start strategies", "Training and the CLI", "Sweeps and clusters",
                 "Reports and videos", "Reliability", "Speed", "Contributing", "API reference"):
        assert page in text, f"the navigation lacks {page!r}"
    # the pictures it shows are served with the site
    for picture in re.findall(r'<img[^>]+src="([^"]+\.png)"', dom):
        with urllib.request.urlopen(f"{site}/{picture}") as response:
            assert response.read(8) == b"\x89PNG\r\n\x1a\n", picture
    assert {"maze.png", "tasks.png"} <= {Path(p).name for p in re.findall(r'<img[^>]+src="([^"]+)"', dom)}
    # and the theme's stylesheet paints the header bar in its primary colour
    screenshot = tmp_path / "start.png"
    done = chromium("--window-size=1280,800", f"--screenshot={screenshot}", f"{site}/index.html")
    assert screenshot.is_file(), done.stderr[-2000:]
    header = iio.imread(screenshot)[10, :, :3].astype(int)
    assert (np.abs(header - MATERIAL_INDIGO).max(axis=1) <= 8).mean() > 0.5, "the header bar is not the theme's"


def test_the_api_reference_renders_the_start_strategies_from_their_docstrings(site):
    dom = rendered(f"{site}/api/agents.html")
    for name in ("StartStateWrapper", "make_start_strategy", "StrategyContext", "AuxSS", "OmegaSS", "GoalDistSS",
                 "ReverseCurriculumSS", "UniformSS", "P0Start", "SACConfig"):
        assert f'id="lava_bridge_mj.agents.{name}"' in dom, f"no API entry for {name}"
    text = text_of(dom)
    # each entry carries its signature and its docstring, parameters included
    assert "StartStateWrapper ( env : Env , strategy : StartStrategy , seed : int | None = None )" in text
    assert "Reset the wrapped env to strategy.states[strategy.sample(rng)] and feed episode lengths back." in text
    assert "Build a start strategy by its CLI name" in text
    assert "delta float floor on W[i]" in text, "AuxSS's parameter table is missing"
    # the RFCL strategies' shared parameters, documented once on their common base class, in both tables
    for name, end in (("RFCLReverseSS", 'id="lava_bridge_mj.agents.RFCLSS"'),
                      ("RFCLSS", 'id="lava_bridge_mj.agents.SACConfig"')):
        entry = text_of(dom[dom.index(f'id="lava_bridge_mj.agents.{name}"'):dom.index(end)])
        assert "per_demo_buffer_size int m, the outcomes a demonstration remembers from its t_i (3" in entry, name


def test_the_api_reference_renders_training_and_the_environment(site):
    training = rendered(f"{site}/api/training.html")
    for path in ("lava_bridge_mj.eval.training.config.RunConfig", "lava_bridge_mj.eval.training.runner.train",
                 "lava_bridge_mj.eval.training.runner.Run"):
        assert f'id="{path}"' in training, f"no API entry for {path}"
    assert "Train config into out_dir and return the finished Run." in text_of(training)
    environment = rendered(f"{site}/api/environment.html")
    for name in ("LavaBridgeEnv", "LavaBridgeVectorEnv", "Layout", "TASKS", "load_demos", "ScriptedExpert"):
        assert f'id="lava_bridge_mj.{name}"' in environment, f"no API entry for {name}"
    assert "A point mass in a two-room maze joined by a narrow bridge over lava." in text_of(environment)
