"""The leaderboard's web page, opened in a real (headless) Chromium: rows, order, tie markers,
markup from submitters shown as text, sorting by clicking, a screenshot.

Needs Debian's ``chromium`` and ``chromium-driver`` (CI installs them); skipped, with the reason,
where they are missing. The page-building checks that need no browser run everywhere.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from scftc_cli.board.html import board_html
from scftc_cli.board.models import Entry, Leaderboard
from scftc_cli.board.ranking import rank_board
from scftc_cli.commands.app import app
from scftc_cli.submission.manifest import parse_manifest
from tests.board.test_board import board_of, entry, ks

runner = CliRunner()
CHROMIUM, DRIVER = shutil.which("chromium"), shutil.which("chromedriver")
HOSTILE = {
    "description": '<script>alert("x")</script><img src=x onerror=alert(1)> & "quotes" <b>bold</b>',
    "authors": ["<i>Mallory</i>", "Eve & Co </td></tr></table>"],
    "paper_url": 'https://example.org/"><script>alert(2)</script>',
    "code_url": "javascript:alert(3)",
}


def hostile_entry() -> Entry:
    """A submission whose manifest strings are full of markup, through the same manifest parser
    that `scftc submit` uses (so the test holds exactly what a submitter can put on the board)."""
    fields = f"'authors': {HOSTILE['authors']!r}, 'description': {HOSTILE['description']!r}"
    source = (
        "SUBMISSION = {'name': 'mallory', 'version': '1', 'entry': 'C', 'license': 'MIT', "
        f"{fields}, 'paper_url': {HOSTILE['paper_url']!r}}}\nclass C:\n    pass\n"
    )
    manifest, _ = parse_manifest(source.encode(), Path("mallory.py"))
    base = entry("mallory", ks(300, 300, 300)).model_dump(by_alias=True)
    base.update(
        kind="submission",
        summary=manifest.description,
        authors=list(manifest.authors),
        paper_url=manifest.paper_url,
        code_url=HOSTILE["code_url"],
        sha256="a" * 64,
        version="1",
    )
    return Entry.model_validate(base)


def board() -> Leaderboard:
    return board_of(
        version=7,
        ranking="the rule",
        entries=[
            entry("alpha", ks(500, 500, 470)),
            entry("beta", ks(500, 500, 466)),  # tied with alpha
            entry("gamma", ks(200, 200, 100)),
            hostile_entry(),
            entry("oracle", ks(500, 500, 490), privileged=True),
        ],
    )


def test_the_page_is_self_contained_and_escapes_every_board_string():
    page = board_html([board()])
    assert "<script>" not in page.split("<script>", 1)[1].split("</script>", 1)[1]  # exactly one script
    assert page.count("<script>") == 1 and "http://" not in page.replace("http-equiv", "")
    assert "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;" in page
    assert "javascript:" not in page.split("<footer>")[0].replace("javascript:alert(3)", "")  # never a link
    assert 'href="javascript' not in page and "alert(2)</script>" not in page
    assert "Content-Security-Policy" in page


def test_the_command_writes_the_page(tmp_path: Path):
    out = tmp_path / "b.html"
    result = runner.invoke(app, ["leaderboard", "--format", "html", "--out", str(out)])
    assert result.exit_code == 0, result.output
    text = out.read_text()
    assert text.startswith("<!DOCTYPE html>") and "scftc-v1" in text and "rls_dob" in text


@pytest.mark.browser
@pytest.mark.skipif(not (CHROMIUM and DRIVER), reason="needs Debian's chromium and chromium-driver")
def test_a_real_browser_shows_ranks_ties_text_and_sorts(tmp_path: Path):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By

    page = tmp_path / "board.html"
    page.write_text(board_html([board()]))
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in (
        "--headless=new",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--window-size=1500,1400",
    ):
        options.add_argument(arg)
    driver = webdriver.Chrome(service=Service(DRIVER), options=options)
    try:
        driver.get(page.as_uri())
        rows = driver.find_elements(By.CSS_SELECTOR, "table#scftc-v1-deployable > tbody > tr[data-name]")
        expected = [r.entry.name for r in rank_board(board()).deployable]
        assert (
            [r.get_attribute("data-name") for r in rows] == expected == ["alpha", "beta", "mallory", "gamma"]
        )
        ranks = [r.find_element(By.CSS_SELECTOR, "td.rank").text for r in rows]
        assert ranks == ["1=", "1=", "3", "4"]
        oracles = driver.find_elements(By.CSS_SELECTOR, "table#scftc-v1-oracles > tbody > tr[data-name]")
        assert [r.get_attribute("data-name") for r in oracles] == ["oracle"]
        # markup is text: the description reads back verbatim, and nothing it contains ran
        mallory = driver.find_element(By.CSS_SELECTOR, 'tr[data-name="mallory"]')
        assert mallory.find_element(By.CSS_SELECTOR, ".summary").text == HOSTILE["description"]
        assert driver.execute_script("return document.scripts.length") == 1
        assert driver.find_elements(By.CSS_SELECTOR, "img") == []
        assert mallory.find_elements(By.CSS_SELECTOR, ".links a") == []  # neither URL is a safe http(s) link
        # expand the cells of one entry
        mallory.find_element(By.CSS_SELECTOR, "button.more").click()
        details = driver.find_element(By.CSS_SELECTOR, 'tbody:has(tr[data-name="mallory"]) tr.details')
        assert details.is_displayed() and "<i>Mallory</i>" in details.text
        # sort by controller name, then reverse
        header = driver.find_elements(By.CSS_SELECTOR, "table#scftc-v1-deployable > thead th")[1]
        header.click()
        names = lambda: [  # noqa: E731
            r.get_attribute("data-name")
            for r in driver.find_elements(
                By.CSS_SELECTOR, "table#scftc-v1-deployable > tbody > tr[data-name]"
            )
        ]
        assert names() == ["alpha", "beta", "gamma", "mallory"]
        header.click()
        assert names() == ["mallory", "gamma", "beta", "alpha"]
        assert driver.save_screenshot(str(tmp_path / "board.png"))
        assert (tmp_path / "board.png").stat().st_size > 10_000
    finally:
        driver.quit()
