"""The report in a real browser (headless Chromium from file://): sorting by a header reorders the
rows, a scene filter hides the others, every picture loads and every local link resolves; the
overview and a track page are saved as screenshots (``$ASSOCBENCH_SCREENSHOTS`` or the test's folder)."""

from __future__ import annotations

import pytest
from browser import broken_images, chromium, full_screenshot, missing_local_targets, screenshot_dir
from report_inputs import PLUGIN, RESULTS, copy_leaderboard, with_plugin

from assocbench.harness.report import build_report, write_report


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    driver = chromium(tmp_path_factory.mktemp("chromium-profile"))
    yield driver
    driver.quit()


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("report")
    planar = with_plugin(copy_leaderboard(RESULTS / "planar", tmp / "planar"))
    out = tmp / "site"
    write_report(build_report([RESULTS, RESULTS / "loop", planar, RESULTS / "lines", RESULTS / "dense"],
                              names=["results", "results/loop", "planar (with a plugin)", "results/lines",
                                     "results/dense"]), out)
    return out


def _column(driver, index: int) -> list[str]:
    return driver.execute_script(
        "return Array.from(document.querySelectorAll('table.filterable tbody tr'))"
        ".filter(r => !r.hidden).map(r => r.cells[arguments[0]].getAttribute('data-v'))", index)


def test_every_page_loads_its_pictures_and_links(browser, report, tmp_path):
    pages = sorted(p.name for p in report.glob("*.html"))
    assert len(pages) == 6
    for name in pages:
        browser.get((report / name).as_uri())
        assert browser.find_elements("css selector", "main h1"), name
        assert broken_images(browser) == [], name
        assert missing_local_targets(browser) == [], name
    browser.get((report / "index.html").as_uri())
    assert PLUGIN in browser.find_element("css selector", "table.ranking").text
    full_screenshot(browser, screenshot_dir(tmp_path) / "report_overview.png")


def test_sorting_and_filtering_a_track_page(browser, report, tmp_path):
    browser.get((report / "planar-closed-loop.html").as_uri())
    headers = browser.find_elements("css selector", "table.filterable thead th")
    names = [h.text.split("\n")[0] for h in headers]
    ate = names.index("ATE")
    before = _column(browser, ate)
    headers[ate].click()
    ascending = _column(browser, ate)
    assert ascending != before
    values = [float(v) for v in ascending if v]
    assert values == sorted(values) and headers[ate].get_attribute("aria-sort") == "ascending"
    headers[ate].click()
    assert [float(v) for v in _column(browser, ate) if v] == sorted(values, reverse=True)

    scene = names.index("scene")
    everything = len(_column(browser, scene))
    browser.execute_script("var s = document.querySelector('select[data-filter=scene]'); s.value = 'park';"
                           "s.dispatchEvent(new Event('change'));")
    shown = _column(browser, scene)
    assert 0 < len(shown) < everything and set(shown) == {"park"}
    assert browser.find_element("css selector", ".count").text == f"showing {len(shown)} of {everything} rows"
    browser.execute_script("var s = document.querySelector('select[data-filter=scene]'); s.value = '';"
                           "s.dispatchEvent(new Event('change'));")
    full_screenshot(browser, screenshot_dir(tmp_path) / "report_planar.png")


def test_no_table_is_cut_off_at_1400_px(browser, report):
    """Every table of every page fits a 1400 px wide window: its last column (the status on a track
    page) is in view without scrolling; the camera page's status column was cut off."""
    browser.set_window_size(1400, 1000)
    for page in sorted(p.name for p in report.glob("*.html")):
        browser.get((report / page).as_uri())
        cut = browser.execute_script("""
            const width = document.documentElement.clientWidth, out = [];
            for (const table of document.querySelectorAll('main table')) {
              const box = table.closest('.scroll') || table;
              const heads = Array.from(table.querySelectorAll('tr:first-child > th')).filter(h => h.offsetParent);
              const last = heads[heads.length - 1];
              if (box.scrollWidth > box.clientWidth + 1 || (last && last.getBoundingClientRect().right > width + 1))
                out.push(table.className + ': ' + (last ? last.textContent : '') + ' ends at ' +
                         Math.round(last ? last.getBoundingClientRect().right : table.scrollWidth) + ' px');
            }
            return out;""")
        assert cut == [], (page, cut)
