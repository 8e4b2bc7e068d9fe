"""The report in a real browser: Debian's headless Chromium driven by selenium through chromedriver. The page loads
with no console error, every figure is decoded, and its blocks are laid out one below the other within the
window, the maps two abreast. Skipped, with the reason, when Chromium, chromedriver or selenium is missing
(.ci/run installs Debian's chromium and chromium-driver)."""

import io
import shutil

import numpy as np
import pytest
from PIL import Image

webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is not installed (pip install -e '.[test]')")
CHROMIUM, CHROMEDRIVER = shutil.which("chromium"), shutil.which("chromedriver")
pytestmark = pytest.mark.skipif(not (CHROMIUM and CHROMEDRIVER),
                                reason="no chromium / chromedriver on PATH (apt-get install chromium chromium-driver)")

FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync")
WIDTH, HEIGHT = 1100, 900
EXIT_GREEN = (0, 166, 81)   # plot/canvas.py EXIT


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    """One headless Chromium for the module, a fresh profile, its console log kept."""
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={tmp_path_factory.mktemp('chromium-profile')}")
    options.add_argument(f"--window-size={WIDTH},{HEIGHT}")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(options=options, service=webdriver.ChromeService(CHROMEDRIVER))
    yield driver
    driver.quit()


def load(browser, path) -> list:
    """Open a file; the console messages of level SEVERE (errors, failed loads) it gave."""
    browser.get_log("browser")   # what an earlier page left
    browser.get(path.as_uri())
    return [entry["message"] for entry in browser.get_log("browser") if entry["level"] == "SEVERE"]


def test_a_console_error_is_seen(browser, tmp_path):
    """The check can fail: a page with a script error and a missing image gives SEVERE console entries."""
    page = tmp_path / "broken.html"
    page.write_text('<html><body><img src="missing.png"><script>console.error("boom")</script></body></html>')
    errors = load(browser, page)
    assert any("boom" in e for e in errors) and any("missing.png" in e for e in errors)


def test_the_report_loads_with_no_console_error_and_all_its_figures(browser, report_page):
    assert load(browser, report_page) == []
    images = browser.execute_script("return Array.from(document.images).map(i => [i.complete, i.naturalWidth, "
                                    "i.naturalHeight, i.id, i.className])")
    assert len(images) >= 6 and all(done and w > 100 and h > 100 for done, w, h, *_ in images)
    assert {"plan", "nt"} <= {i[3] for i in images} and sum(i[4] == "map" for i in images) == 4


def test_the_layout_of_the_report(browser, report_page, tmp_path):
    """The header and the five blocks one below the other, none wider than the window (no sideways scroll); the
    maps two abreast; the screenshot of the plan shows the exit in its green."""
    load(browser, report_page)
    rects = browser.execute_script(
        "return ['header', 'scene', 'evacuation', 'doors', 'remaining', 'maps'].map(id => {"
        "const r = document.getElementById(id).getBoundingClientRect(); return [r.left, r.top, r.width, r.height];})")
    rects = np.array(rects)
    assert np.all(rects[:, 2] > 300) and np.all(rects[:, 3] > 20)
    assert np.all(rects[1:, 1] >= rects[:-1, 1] + rects[:-1, 3] - 1)    # each block below the one before
    assert browser.execute_script("return document.documentElement.scrollWidth") <= WIDTH
    maps = np.array(browser.execute_script(
        "return Array.from(document.querySelectorAll('img.map')).map(i => {"
        "const r = i.getBoundingClientRect(); return [r.left, r.top, r.width];})"))
    assert maps[0, 1] == pytest.approx(maps[1, 1]) and maps[1, 0] >= maps[0, 0] + maps[0, 2] - 1
    shot = browser.find_element("id", "plan").screenshot_as_png
    (tmp_path / "plan.png").write_bytes(shot)
    image = np.asarray(Image.open(io.BytesIO(shot)).convert("RGB")).astype(int)
    assert image.shape[0] > 200 and image.shape[1] > 400
    assert np.any(np.all(np.abs(image - EXIT_GREEN) <= 12, axis=-1))
