"""The built docs site in a real browser (headless Chromium from file://): the home page, the
leaderboard page and the HTML report published in the site load every picture and every local
link resolves; screenshots of the home page and the report's overview.

It needs a built site: ``ASSOCBENCH_DOCS_SITE`` names the folder of ``mkdocs build --site-dir``
(``.ci/run`` builds it with --strict, then runs this file); without it the test skips."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from browser import broken_images, chromium, full_screenshot, missing_local_targets, screenshot_dir

PAGES = ("index.html", "leaderboard/index.html", "howto/report/index.html", "tracks/planar/index.html",
         "report/index.html", "report/planar-closed-loop.html")


@pytest.fixture(scope="module")
def site() -> Path:
    folder = os.environ.get("ASSOCBENCH_DOCS_SITE")
    if not folder:
        pytest.skip("no built docs site: set ASSOCBENCH_DOCS_SITE to a `mkdocs build --site-dir` folder (.ci/run does)")
    site = Path(folder)
    assert (site / "index.html").is_file(), f"ASSOCBENCH_DOCS_SITE={folder} holds no built site (no index.html)"
    return site


def test_the_docs_and_their_report_load_every_picture_and_link(site, tmp_path):
    browser = chromium(tmp_path / "profile")
    try:
        for page in PAGES:
            browser.get((site / page).as_uri())
            assert browser.find_elements("css selector", "h1"), page
            assert broken_images(browser) == [], page
            assert missing_local_targets(browser) == [], page
            if page in ("index.html", "report/index.html"):
                full_screenshot(browser, screenshot_dir(tmp_path) / f"docs_{page.replace('/', '_')}.png")
        browser.get((site / "leaderboard/index.html").as_uri())
        browser.find_element("link text", "Open the HTML leaderboard").click()
        # mkdocs links to folders (directory URLs); a web server answers a folder with its index.html
        assert browser.current_url.endswith("/report/"), browser.current_url
        browser.get(browser.current_url + "index.html")
        assert browser.find_element("css selector", "main h1").text == "Leaderboard across tracks"
    finally:
        browser.quit()
