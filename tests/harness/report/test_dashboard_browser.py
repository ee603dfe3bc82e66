"""The dashboard in a real browser: headless Chromium opens index.html from the file system.

Needs Debian's ``chromium`` and ``chromium-driver`` (the Makefile's DEBS install them); without
them the test fails and says so, it does not skip. Prints the page's size and load times (not
asserted: timings here are the machine's, not the page's).
"""

from __future__ import annotations

import shutil
import time

import pytest

from helpers import chromium, wait_for

from harness import report

LOAD_TIMES = """
    const t = performance.getEntriesByType("navigation")[0];
    return [t.domInteractive, t.domContentLoadedEventEnd, t.loadEventEnd];"""


@pytest.fixture(scope="module")
def page(tmp_path_factory, small_run_dir):
    """A real run's page, with images shown at 64 px so the 96 px runs also get native files."""
    run = small_run_dir(tmp_path_factory.mktemp("browser") / "run")
    return report.build_report(run, shown_px=64)


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    driver = chromium(tmp_path_factory.mktemp("chromium-profile"))
    yield driver
    driver.quit()


def _errors(driver) -> list:
    return [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]


def _open(driver, path, fragment: str = ""):
    driver.get(path.resolve().as_uri() + fragment)
    wait_for(driver, "return document.readyState === 'complete'", "the page to load")


def test_overview_answers_first_and_loads_quickly(page, browser):
    _open(browser, page)
    interactive, ready, loaded = browser.execute_script(LOAD_TIMES)
    print(f"\nindex.html {page.stat().st_size / 1e6:.2f} MB: interactive {interactive:.0f} ms, "
          f"DOMContentLoaded {ready:.0f} ms, load {loaded:.0f} ms")
    shown = browser.execute_script(
        "return [...document.querySelectorAll('section.view')].filter(s => s.offsetParent)"
        ".map(s => s.id)")
    assert shown == ["overview"]
    rows = browser.execute_script(
        "return [...document.querySelectorAll('table.summary')].filter(t => !t.hidden)"
        ".map(t => t.rows.length)")
    assert len(rows) == 1 and rows[0] >= 1 + 8  # a header and one row per technique
    scenes = browser.find_elements("css selector", "table.scenes a b")
    assert [s.text for s in scenes] == ["box_plane", "sphere_plane"]
    assert not _errors(browser)


def test_a_scene_draws_its_plot_and_opens_a_run_at_native_size(page, browser):
    """The scene's plot has one panel per image size and a point per run; a click on a run row
    shows its images, a click on its V opens it at native size (96 px, from the file beside)."""
    _open(browser, page, "#scene-box_plane")
    wait_for(browser, "return document.querySelectorAll("
              "'#scene-box_plane .cost-accuracy svg.chart').length === 2", "two plot panels")
    points = browser.execute_script(
        "return document.querySelectorAll('#scene-box_plane svg.chart circle.point').length")
    assert points > 10
    row = browser.find_element(
        "xpath", "//section[@id='scene-box_plane']//tr[@data-run][td[2]='96x96']"
        "[td[4][starts-with(normalize-space(.), 'ok')]]")
    row.click()
    assert "selected" in row.get_attribute("class")
    browser.find_element("css selector", "#scene-box_plane figure[data-slot=v] img").click()
    size = wait_for(browser, """
        const img = document.querySelector('#overlay img');
        return !document.getElementById('overlay').hidden && img.complete && img.naturalWidth
            ? [img.naturalWidth, img.getBoundingClientRect().width, img.src] : null;""",
                     "the native-size image")
    assert size[0] == 96 and size[1] == 96 and size[2].endswith(".png")
    browser.find_element("css selector", "#overlay button[data-zoom='4']").click()
    assert browser.execute_script(
        "return document.querySelector('#overlay img').getBoundingClientRect().width") == 384
    assert not _errors(browser)


def test_index_copied_alone_shows_every_image(page, browser, tmp_path):
    """index.html in an empty folder: every view's images load (they are inside the file) and
    the console stays clean."""
    alone = tmp_path / "index.html"
    shutil.copy(page, alone)
    _open(browser, alone)
    loaded = 0
    for view in browser.execute_script(
            "return [...document.querySelectorAll('section.view')].map(s => s.id)"):
        browser.execute_script(f"location.hash = '#{view}'")
        images_here = wait_for(browser, f"""
            const imgs = [...document.getElementById('{view}').querySelectorAll('img[src]')];
            return imgs.every(i => i.complete) ? imgs.map(i => [i.naturalWidth, i.alt]) : null;""",
                                f"the images of {view}") if view != "stability" else []
        broken = [alt for width, alt in images_here if not width]
        assert not broken, (view, broken)
        loaded += len(images_here)
    assert loaded > 10
    assert not _errors(browser)


def test_a_hostile_scene_name_runs_no_script(browser, tmp_path, make_results):
    """A scene named ``x" onerror="document.title='PWNED'"``: the title stays, nothing ran."""
    from helpers import hostile_folder

    folder = hostile_folder(tmp_path / "run", make_results)
    index = report.build_report(folder)
    _open(browser, index)
    title = browser.title
    for link in browser.find_elements("css selector", "nav a"):
        link.click()
        time.sleep(0.2)
    browser.find_element("css selector", "nav .scene-links a").click()
    wait_for(browser, "return document.querySelector('section.scene.shown svg.chart')",
              "the hostile scene's plot")
    assert browser.title == title and "PWNED" not in title
    assert browser.execute_script("return typeof alert === 'function' && !window.PWNED")
    assert not _errors(browser)


def test_the_scale_view_draws_its_charts(browser, tmp_path, make_results):
    """The Scale view of a hand-made family folder: the cost chart's one family panel with a
    line per technique, the fronts' four size panels, the crossover table, a clean console.
    Catches: a view the nav does not reach, chart specs the plotter cannot draw (a JS error,
    no panel), the fronts not split per size."""
    from helpers import scale_folder

    index = report.build_report(scale_folder(tmp_path / "run", make_results))
    _open(browser, index)
    browser.find_element("css selector", "nav a[href='#scale']").click()
    wait_for(browser, "return document.querySelector('#scale-front-0 svg.chart')",
              "the Scale view's charts")
    panels = browser.execute_script(
        "return ['scale-cost', 'scale-front-0'].map(id => "
        "document.querySelectorAll('#' + id + ' svg.chart').length)")
    assert panels == [1, 4]
    lines = browser.execute_script(
        "return document.querySelectorAll('#scale-cost svg.chart polyline.line').length")
    assert lines == 2
    assert "31,623 triangles" in browser.find_element("css selector", "table.crossovers").text
    assert not _errors(browser)


def test_many_scenes_wrap_in_the_header_without_a_sideways_scroll(browser, tmp_path,
                                                                  make_results):
    """30 scenes with long names: their links wrap onto more header lines and the page never
    scrolls sideways at 1400 px. Catches the links written with nothing between them (each
    nowrap, so no place to break: make bench's 21 scenes ran past the window's edge)."""
    runs = [{"scene": f"a_rather_long_scene_name_{i:02d}", "params": {"res": 512}}
            for i in range(30)]
    index = report.build_report(make_results(tmp_path / "run", runs))
    _open(browser, index)
    wide, shown, lines = browser.execute_script(
        "const links = [...document.querySelectorAll('nav .scene-links a')];"
        "return [document.documentElement.scrollWidth, window.innerWidth,"
        " new Set(links.map(a => Math.round(a.getBoundingClientRect().top))).size]")
    assert wide <= shown, (wide, shown)
    assert lines >= 3
