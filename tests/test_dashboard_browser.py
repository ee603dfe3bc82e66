"""The dashboard in a real browser: headless Chromium opens index.html from the file system.

Needs Debian's ``chromium`` and ``chromium-driver`` (the Makefile's DEBS install them); without
them the test fails and says so, it does not skip.
"""

from __future__ import annotations

import os
import shutil
import time

import pytest

from harness import report

CHROMIUM = os.environ.get("SHADOWBENCH_CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("SHADOWBENCH_CHROMEDRIVER", "/usr/bin/chromedriver")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--window-size=1400,1000"]
DRAW_TIMEOUT_S = 60


@pytest.fixture(scope="module")
def page(tmp_path_factory, gl_context):
    from test_report import make_run_dir

    run = make_run_dir(tmp_path_factory.mktemp("browser") / "run")
    return report.build_report(run)


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    missing = [p for p in (CHROMIUM, CHROMEDRIVER) if not shutil.which(p)]
    if missing:
        pytest.fail(f"{', '.join(missing)} not found: install Debian's chromium and "
                    "chromium-driver (make setup does), or set SHADOWBENCH_CHROMIUM and "
                    "SHADOWBENCH_CHROMEDRIVER")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in FLAGS + [f"--user-data-dir={tmp_path_factory.mktemp('chromium-profile')}"]:
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    yield driver
    driver.quit()


def _wait_for(driver, script: str, what: str):
    deadline = time.monotonic() + DRAW_TIMEOUT_S
    while time.monotonic() < deadline:
        value = driver.execute_script(script)
        if value:
            return value
        time.sleep(0.2)
    pytest.fail(f"timed out after {DRAW_TIMEOUT_S} s waiting for {what}")


def test_dashboard_draws_every_plot_and_image_without_console_errors(page, browser):
    browser.get(page.resolve().as_uri())
    _wait_for(browser, "return document.readyState === 'complete'", "the page to load")
    plots = browser.execute_script(
        "return [...document.querySelectorAll('div.plotly-graph-div')].map(d => d.id)")
    assert len(plots) == 2 * 2  # two scenes, a scatter and the cost bars each
    undrawn = _wait_for(browser, """
        const divs = [...document.querySelectorAll('div.plotly-graph-div')];
        return divs.every(d => d.querySelector('svg.main-svg')) ? 'drawn' : null;""",
                        "every plotly div to draw its svg")
    assert undrawn == "drawn"
    markers = browser.execute_script(
        "return document.getElementById('box_plane-cost-accuracy')"
        ".querySelectorAll('g.points path.point').length")
    assert markers > 0
    images = browser.execute_script("""
        return [...document.images].map(i => [i.getAttribute('src'), i.complete,
                                              i.naturalWidth]);""")
    assert len(images) > 10
    broken = [src for src, complete, width in images if not complete or width == 0]
    assert not broken, f"images that did not load: {broken}"
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert not errors, f"console errors: {errors}"
    shot = page.parent / "dashboard-screenshot.png"
    for _ in range(3):  # the page reflows at each window size; settle on its full height
        height = browser.execute_script("return document.documentElement.scrollHeight")
        browser.set_window_size(1400, min(16000, height + 200))
    assert browser.save_screenshot(str(shot)) and shot.stat().st_size > 10_000
    print(f"screenshot: {shot}")


def test_metric_buttons_switch_the_scatter(page, browser):
    """Clicking "mae" shows the mae traces (and their Pareto front) and renames the y axis."""
    browser.get(page.resolve().as_uri())
    _wait_for(browser, "return document.querySelector('#box_plane-cost-accuracy svg.main-svg')",
              "the scatter")
    title = ("return document.getElementById('box_plane-cost-accuracy')"
             ".layout.yaxis.title.text")
    assert browser.execute_script(title).startswith("edge_mae")
    buttons = browser.find_elements(
        "css selector", "#box_plane-cost-accuracy g.updatemenu-button")
    labels = [b.text for b in buttons]
    assert labels[:3] == ["edge_mae", "mae", "wrong_pct"]
    buttons[1].click()
    _wait_for(browser, title.replace("return ", "return (") + ").startsWith('mae')",
              "the y axis to switch to mae")
    visible = browser.execute_script(
        "return document.getElementById('box_plane-cost-accuracy').data"
        ".filter(t => t.visible === true).map(t => [t.mode, t.y.length]);")
    assert any(mode == "lines" for mode, _ in visible)
    assert not [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
