"""Headless Chromium for the browser tests (Debian's ``chromium`` and ``chromium-driver``, driven
by selenium). Without them a test skips with one line, unless ``ASSOCBENCH_REQUIRE_BROWSER=1``
(set by ``.ci/run``), where the skip is a failure: CI must never pass by not looking."""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from urllib.parse import unquote, urlparse

import pytest

REQUIRED = os.environ.get("ASSOCBENCH_REQUIRE_BROWSER") == "1"
# without the background-networking flags Chromium's own services dial out, which a closed network refuses
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--disable-dev-shm-usage", "--hide-scrollbars")


def unavailable(reason: str) -> None:
    """Skip with ``reason``, or fail where a browser is required."""
    if REQUIRED:
        pytest.fail(f"{reason}, and ASSOCBENCH_REQUIRE_BROWSER=1 says the browser tests must run")
    pytest.skip(reason)


def chromium(profile: Path):
    """A headless Chromium (a fresh, empty profile in ``profile``), or a skip."""
    binary = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    if not binary or not driver:
        unavailable("no Chromium here (apt-get install chromium chromium-driver)")
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        unavailable("selenium is not installed (pip install -e '.[test]')")
    options = webdriver.ChromeOptions()
    options.binary_location = binary
    for flag in FLAGS + (f"--user-data-dir={profile}", "--window-size=1400,1000"):
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(driver), options=options)


def screenshot_dir(tmp_path: Path) -> Path:
    """Where screenshots go: ``$ASSOCBENCH_SCREENSHOTS`` or the test's own folder."""
    folder = Path(os.environ.get("ASSOCBENCH_SCREENSHOTS") or tmp_path / "screens")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def full_screenshot(driver, path: Path, width: int = 1400, max_height: int = 4000) -> None:
    """A screenshot of the whole page (up to ``max_height`` pixels)."""
    height = driver.execute_script("return document.documentElement.scrollHeight")
    driver.set_window_size(width, min(max(height, 600), max_height))
    driver.save_screenshot(str(path))
    driver.set_window_size(width, 1000)


def broken_images(driver) -> list[str]:
    """The page's images that did not load (not complete, or no pixels)."""
    return driver.execute_script(
        "return Array.from(document.images).filter(i => !i.complete || i.naturalWidth === 0).map(i => i.src)")


def missing_local_targets(driver) -> list[str]:
    """The page's links and images to ``file://`` URLs whose file does not exist (a folder
    counts when it holds ``index.html``, as a static site is served)."""
    urls = driver.execute_script("return Array.from(document.querySelectorAll('a[href]')).map(a => a.href)"
                                 ".concat(Array.from(document.images).map(i => i.src))")
    missing = []
    for url in urls:
        parsed = urlparse(url)
        if parsed.scheme != "file":
            continue
        path = Path(unquote(parsed.path))
        if not (path.is_file() or (path / "index.html").is_file()):
            missing.append(url)
    return sorted(set(missing))
