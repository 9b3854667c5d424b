#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Browser test of the 3-D replay (docs/replay.md): flies a short triangle with `fnmpc run`,
writes its replay.html with `fnmpc report --replay-only`, copies the page alone into an
empty folder and opens it from file:// in headless Chromium with every host name
unresolvable. Checks: the page reaches status 'ready', logs no error and requests nothing
but itself; the 3-D view is not blank; moving the time slider moves the drawn vehicles and
changes the picture.
Usage: replay_browser_test.py FNMPC_EXE SCENARIO [--keep DIR]"""
import argparse
import io
import os
import shutil
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from devtools import Browser  # noqa: E402

BACKGROUND = np.array([0x1D, 0x21, 0x27]) / 255.0  # scene.background of replay.js
BAR_HEIGHT = 44  # control bar at the bottom (replay.html)


def check(condition, what):
    if not condition:
        raise AssertionError(what)
    print("ok:", what)


def image(png):
    return mpimg.imread(io.BytesIO(png), format="png")[:, :, :3]


def scene_region(img):
    """The 3-D view without the title lines, the error plot and the control bar."""
    h, w, _ = img.shape
    return img[60:h - BAR_HEIGHT - 150, : int(w * 0.6)]


def set_slider(browser, value):
    return browser.evaluate(
        "(() => { const s = document.getElementById('slider'); s.value = %r;"
        " s.dispatchEvent(new Event('input')); return [fnmpcReplay.time(),"
        " fnmpcReplay.screenPositions(), document.getElementById('time').textContent]; })()"
        % value)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("fnmpc")
    p.add_argument("scenario")
    p.add_argument("--keep", help="keep the run folder and screenshots here")
    a = p.parse_args()
    work = a.keep or tempfile.mkdtemp(prefix="fnmpc-replay-test-")
    os.makedirs(work, exist_ok=True)
    try:
        run_dir = os.path.join(work, "run")
        subprocess.run([a.fnmpc, "run", a.scenario, "--duration", "26", "--seed", "3", "-q",
                        "-o", run_dir], check=True)
        subprocess.run([a.fnmpc, "report", run_dir, "--replay-only"], check=True)
        copied = os.path.join(work, "copy")
        os.makedirs(copied, exist_ok=True)
        page = os.path.join(copied, "replay.html")
        shutil.copy(os.path.join(run_dir, "replay.html"), page)

        browser = Browser()
        try:
            browser.call("Page.navigate", url="file://" + page)
            status = browser.wait_for(
                "document.body && document.body.dataset.status !== 'loading' &&"
                " document.body.dataset.status")
            check(status == "ready", f"page status is 'ready' (got {status!r})")
            frames = browser.evaluate("fnmpcReplay.frames")
            check(frames > 100, f"replay holds the run ({frames} frames)")

            t_a, pos_a, label_a = set_slider(browser, 8.0)
            browser.evaluate("new Promise(r => requestAnimationFrame(() => r(1)))")
            shot_a = image(browser.screenshot_png())
            region = scene_region(shot_a)
            drawn = np.abs(region - BACKGROUND).max(axis=2) > 0.08
            check(drawn.mean() > 0.01, f"canvas not blank ({100 * drawn.mean():.1f} % drawn)")

            t_b, pos_b, label_b = set_slider(browser, 14.0)
            browser.evaluate("new Promise(r => requestAnimationFrame(() => r(1)))")
            shot_b = image(browser.screenshot_png())
            check(abs(t_a - 8.0) < 1e-6 and abs(t_b - 14.0) < 1e-6,
                  f"slider sets the time ({t_a}, {t_b}; labels {label_a!r}, {label_b!r})")
            moved = max(np.hypot(pa[0] - pb[0], pa[1] - pb[1]) for pa, pb in zip(pos_a, pos_b))
            check(moved > 5.0, f"moving the slider moves the drawn vehicles (up to {moved:.0f} px)")
            changed = (np.abs(scene_region(shot_a) - scene_region(shot_b)).max(axis=2) > 0.08)
            check(changed.sum() > 200, f"the picture changes ({changed.sum()} pixels)")
            if a.keep:
                with open(os.path.join(work, "replay-a.png"), "wb") as f:
                    f.write(browser.screenshot_png())

            errors = browser.errors()
            check(not errors, f"no console errors ({errors[:3]})")
            requests = [u for u in browser.requests() if not u.startswith(("file:", "data:", "blob:"))]
            check(not requests, f"no network requests ({requests[:3]})")
        finally:
            browser.close()
    finally:
        if not a.keep:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
