"""The leaderboard's web page, opened in a real (headless) Chromium: rows, order, tie markers,
markup from submitters shown as text, sorting by clicking, the page fitting a 1400 px window, every
part the markdown board carries, and the profile chart's lines against ``pooled_profile``.

Needs Debian's ``chromium`` and ``chromium-driver`` (CI installs them); skipped, with the reason,
where they are missing. The page-building checks that need no browser run everywhere.
"""

from __future__ import annotations

import functools
import math
import re
import shutil
from collections.abc import Iterator
from html.parser import HTMLParser
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest
from typer.testing import CliRunner

from scftc_cli.board.html import board_html
from scftc_cli.board.models import BoardEvent, Entry, Leaderboard, Round
from scftc_cli.board.ranking import pooled_settled, pooled_settled_profile_of, rank_board
from scftc_cli.board.render import board_markdown, pooled_text
from scftc_cli.board.rounds import commitment
from scftc_cli.board.store import default_board_path, read_board
from scftc_cli.commands.app import app
from scftc_cli.scoring import settled_profile_taus
from scftc_cli.spec import V1, get_spec
from scftc_cli.statistics import PROFILE_TAUS_DEG, pooled_profile
from scftc_cli.submission.manifest import parse_manifest
from scftc_cli.versions import published_names
from tests.board.test_board import board_of, entry, ks, round_one

if TYPE_CHECKING:
    from selenium.webdriver.remote.webdriver import WebDriver
    from selenium.webdriver.remote.webelement import WebElement

runner = CliRunner()
CHROMIUM, DRIVER = shutil.which("chromium"), shutil.which("chromedriver")
WINDOW = (1400, 900)
COMMITTED = published_names()  # every committed board
HOSTILE = {
    "description": '<script>alert("x")</script><img src=x onerror=alert(1)> & "quotes" <b>bold</b>',
    "authors": ["<i>Mallory</i>", "Eve & Co </td></tr></table>"],
    "paper_url": 'https://example.org/"><script>alert(2)</script>',
    "code_url": "javascript:alert(3)",
}
browser = pytest.mark.skipif(not (CHROMIUM and DRIVER), reason="needs Debian's chromium and chromium-driver")


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


def changed(e: Entry, **fields: object) -> Entry:
    """``e`` with ``fields`` replaced, validated again as a board would read it."""
    return Entry.model_validate({**e.model_dump(by_alias=True), **fields})


FAILURE = "the sandbox stopped it after 600 s <timeout>"


def rich_board() -> Leaderboard:
    """A board with every part the markdown board can show: a flagged entry (settles far more on
    the public draw), a learned built-in, an oracle, a pending submission in the open round 2, a
    failed one in round 1, and 25 history events (20 shown)."""
    round_two = Round(
        number=2,
        commitment=commitment(bytes.fromhex("7a" * 32)),
        opened_board_version=3,
        opened_utc="2026-01-02T00:00:00Z",
        status="open",
    )
    submission = {"kind": "submission", "sha256": "b" * 64, "version": "0.3"}
    return Leaderboard(
        version=9,
        updated_utc="2026-01-03T00:00:00Z",
        ranking="the rule",
        rounds=[round_one(), round_two],
        entries=[
            entry("alpha", ks(500, 500, 470)),
            entry("sly", ks(300, 300, 300), public=ks(450, 450, 450)),
            changed(entry("learner", ks(400, 350, 200)), training={"seed": 3, "seeds_tried": 2}),
            entry("oracle", ks(500, 500, 490), privileged=True),
            changed(
                entry("newcomer", ks(480, 470, 460)),
                status="pending",
                sealed=[],
                sealed_salt=None,
                round=2,
                added_board_version=4,
                **submission,
            ),
            changed(entry("broken", ks(0, 0, 0)), status="failed", sealed=[], failure=FAILURE, **submission),
        ],
        history=[
            BoardEvent(
                board_version=i, utc=f"2026-01-02T00:00:{i:02d}Z", action="added", name=f"entry{i:02d}"
            )
            for i in range(1, 26)
        ],
    )


@functools.cache
def committed_page() -> str:
    """The page for every committed board (what ``scftc leaderboard --format html`` writes)."""
    return board_html([read_board(default_board_path(v), v) for v in COMMITTED])


BLOCKS = {"p", "div", "li", "td", "th", "tr", "dt", "dd", "h1", "h2", "h3", "section", "table", "br"}


class _Page(HTMLParser):
    """The text a reader can see, hidden details included (everything outside script and style),
    and every start tag with its attributes."""

    def __init__(self) -> None:
        super().__init__()
        self.parts: list[str] = []
        self.tags: list[tuple[str, list[tuple[str, str | None]]]] = []
        self._skip = 0

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append((tag, attrs))
        self._skip += tag in ("script", "style")
        self.parts.append(" " if tag in BLOCKS else "")

    def handle_endtag(self, tag: str) -> None:
        self._skip -= tag in ("script", "style")
        self.parts.append(" " if tag in BLOCKS else "")

    def handle_data(self, data: str) -> None:
        if not self._skip:
            self.parts.append(data)


def text_of(page: str) -> str:
    parser = _Page()
    parser.feed(page)
    return re.sub(r"\s+", " ", "".join(parser.parts))


def tags_of(page: str) -> list[tuple[str, list[tuple[str, str | None]]]]:
    parser = _Page()
    parser.feed(page)
    return parser.tags


def unmark(line: str) -> str:
    """A markdown bullet as plain text (no bullet, no backticks), spaces normalised."""
    return re.sub(r"\s+", " ", line.removeprefix("- ").replace("`", ""))


# ------------------------------------------------------------------------ the page, no browser
def test_the_page_is_self_contained_and_escapes_every_board_string():
    page = board_html([board()])
    assert "<script>" not in page.split("<script>", 1)[1].split("</script>", 1)[1]  # exactly one script
    assert page.count("<script>") == 1 and "http://" not in page.replace("http-equiv", "")
    assert "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;" in page
    assert "javascript:" not in page.split("<footer>")[0].replace("javascript:alert(3)", "")  # never a link
    assert 'href="javascript' not in page and "alert(2)</script>" not in page
    assert "Content-Security-Policy" in page
    tags = tags_of(page)  # nothing that could fetch: no src attribute, no link, image or frame
    assert not any(name == "src" for _, attrs in tags for name, _ in attrs)
    assert not {tag for tag, _ in tags} & {"link", "img", "iframe", "object", "embed"}


def test_the_command_writes_the_page(tmp_path: Path):
    out = tmp_path / "b.html"
    result = runner.invoke(app, ["leaderboard", "--format", "html", "--out", str(out)])
    assert result.exit_code == 0, result.output
    text = out.read_text()
    assert text.startswith("<!DOCTYPE html>") and "scftc-v1" in text and "rls_dob" in text


def test_the_page_says_built_in_never_builtin():
    for page in (committed_page(), board_html([rich_board()])):
        text = text_of(page)
        assert "built-in" in text and "builtin" not in text


def test_the_flag_history_and_rounds_read_as_on_the_markdown_board():
    b = rich_board()
    markdown, text = board_markdown(b), text_of(board_html([b]))
    flagged = markdown.split("## Flagged\n\n", 1)[1].split("\n\n", 1)[0].splitlines()
    assert len(flagged) == 1 and "sly" in flagged[0]
    assert unmark(flagged[0]) in text  # the flag's explanation, word for word
    history = markdown.split("## History\n\n", 1)[1].strip().splitlines()
    assert len(history) == 20 and all(unmark(line) in text for line in history)
    assert "entry05" not in text and "entry06" in text  # the last 20 of 25 events
    for r in b.rounds:
        assert r.commitment in text
    assert b.rounds[0].secret in text and "Round 2" not in text  # round 2 holds an entry: no such note
    assert f"broken (submission 0.3, round 1): {FAILURE}" in text


def test_an_open_round_without_entries_says_so():
    text = text_of(committed_page())
    for version in published_names():
        board = read_board(default_board_path(version), version)
        assert board.open_round is not None and not any(e.status == "pending" for e in board.entries)
        assert f"Round {board.open_round.number} is open and holds no entry yet." in text


# ----------------------------------------------------------------------------------- in a browser
@pytest.fixture(scope="module")
def driver() -> Iterator[WebDriver]:
    """One headless Chromium for the module, its window 1400 x 900."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM or ""
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"):
        options.add_argument(arg)
    options.add_argument(f"--window-size={WINDOW[0]},{WINDOW[1]}")
    chrome = webdriver.Chrome(service=Service(DRIVER), options=options)
    try:
        yield chrome
    finally:
        chrome.quit()


def load(driver: WebDriver, tmp_path: Path, page: str) -> None:
    path = tmp_path / "board.html"
    path.write_text(page)
    driver.get(path.as_uri())


def names(driver: WebDriver, selector: str) -> list[str]:
    from selenium.webdriver.common.by import By

    return [r.get_attribute("data-name") for r in driver.find_elements(By.CSS_SELECTOR, selector)]


@pytest.mark.browser
@browser
def test_a_real_browser_shows_ranks_ties_text_and_sorts(driver: WebDriver, tmp_path: Path):
    from selenium.webdriver.common.by import By

    load(driver, tmp_path, board_html([board()]))
    deployable = "table#scftc-v1-deployable-table > tbody > tr[data-name]"
    expected = [r.entry.name for r in rank_board(board()).deployable]
    assert names(driver, deployable) == expected == ["alpha", "beta", "mallory", "gamma"]
    rows = driver.find_elements(By.CSS_SELECTOR, deployable)
    assert [r.find_element(By.CSS_SELECTOR, "td.rank").text for r in rows] == ["1=", "1=", "3", "4"]
    assert names(driver, "table#scftc-v1-oracles-table > tbody > tr[data-name]") == ["oracle"]
    # markup is text: the description reads back verbatim, and nothing it contains ran
    mallory = driver.find_element(By.CSS_SELECTOR, 'tr[data-name="mallory"]')
    assert (
        mallory.find_element(By.CSS_SELECTOR, ".summary").get_attribute("textContent")
        == HOSTILE["description"]
    )
    assert driver.execute_script("return document.scripts.length") == 1
    assert driver.find_elements(By.CSS_SELECTOR, "img") == []
    assert mallory.find_elements(By.CSS_SELECTOR, "a") == []  # neither URL is a safe http(s) link
    # expand the details of one entry: the authors as text, the javascript: URL as text, not a link
    mallory.find_element(By.CSS_SELECTOR, "button.more").click()
    details = driver.find_element(By.CSS_SELECTOR, 'tbody:has(tr[data-name="mallory"]) tr.details')
    assert (
        details.is_displayed() and "<i>Mallory</i>" in details.text and "javascript:alert(3)" in details.text
    )
    assert [a.get_attribute("href") for a in details.find_elements(By.CSS_SELECTOR, "dl a")] == []
    # sort by controller name, then reverse
    header = driver.find_elements(By.CSS_SELECTOR, "table#scftc-v1-deployable-table > thead th")[1]
    header.click()
    assert names(driver, deployable) == ["alpha", "beta", "gamma", "mallory"]
    header.click()
    assert names(driver, deployable) == ["mallory", "gamma", "beta", "alpha"]


@pytest.mark.browser
@browser
def test_every_committed_board_fits_a_1400_px_window(driver: WebDriver, tmp_path: Path):
    from selenium.webdriver.common.by import By

    load(driver, tmp_path, committed_page())
    assert driver.execute_script("return window.innerWidth") == WINDOW[0]
    assert [s.get_attribute("id") for s in driver.find_elements(By.CSS_SELECTOR, "section.board")] == list(
        COMMITTED
    )

    def overflow() -> int:
        return driver.execute_script("return document.documentElement.scrollWidth - window.innerWidth")

    assert overflow() <= 0
    # the last column of every table (the flag, the last class) ends inside the window
    rights = driver.execute_script(
        "return Array.from(document.querySelectorAll('table')).map("
        "t => t.querySelector('th:last-child, td:last-child').getBoundingClientRect().right)"
    )
    assert rights and max(rights) <= WINDOW[0]
    for button in driver.find_elements(By.CSS_SELECTOR, "button.more"):  # every entry's details open
        driver.execute_script("arguments[0].click()", button)
    assert overflow() <= 0
    assert driver.execute_script("return performance.getEntriesByType('resource').length") == 0
    assert driver.save_screenshot(str(tmp_path / "board.png"))


@pytest.mark.browser
@browser
def test_the_profile_chart_draws_each_ranked_entrys_pooled_profile(driver: WebDriver, tmp_path: Path):
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    load(driver, tmp_path, committed_page())
    for version in COMMITTED:
        ranking = rank_board(read_board(default_board_path(version), version))
        spec = get_spec(version)
        classes = spec.ranked_classes
        # a board sealed with the ranked gate's profile draws it; an older one its final-error profile
        gate_profile = all(
            pooled_settled_profile_of(r.entry.sealed, classes) is not None for r in ranking.deployable
        )
        grid = settled_profile_taus(spec.gates) if gate_profile else PROFILE_TAUS_DEG
        lo, hi = math.log10(grid[0]), math.log10(grid[-1])
        chart = driver.find_element(By.CSS_SELECTOR, f"figure#{version}-profile-chart")
        lines = chart.find_elements(By.CSS_SELECTOR, "svg polyline.series")
        ranked = [r.entry.name for r in ranking.deployable]
        assert [line.get_attribute("data-key") for line in lines] == ranked
        assert [
            li.get_attribute("data-key") for li in chart.find_elements(By.CSS_SELECTOR, "ol.legend li")
        ] == ranked
        area = chart.find_element(By.CSS_SELECTOR, "svg rect.plot-area")
        x0, y0, w, h = (float(area.get_attribute(a)) for a in ("x", "y", "width", "height"))
        for r, line in zip(ranking.deployable, lines, strict=True):
            points = np.array([p.split(",") for p in line.get_attribute("points").split()], dtype=float)
            taus = 10 ** (lo + (points[:, 0] - x0) / w * (hi - lo))
            shown = 1 - (points[:, 1] - y0) / h
            cells = [c for c in r.entry.sealed if c.sensor is None and c.fault_class in classes]
            expected = (
                pooled_settled_profile_of(r.entry.sealed, classes)
                if gate_profile
                else pooled_profile(
                    np.array([c.final_error_deg.profile for c in cells]), np.array([c.n for c in cells])
                )
            )
            np.testing.assert_allclose(taus, grid, rtol=1e-3)
            np.testing.assert_allclose(shown, expected, atol=1e-3)
        assert "docs/statistics.md" in chart.find_element(By.XPATH, "..").text  # the how-to-read note
        # hovering a name in the legend picks out its line
        ActionChains(driver).move_to_element(
            chart.find_elements(By.CSS_SELECTOR, "ol.legend li")[1]
        ).perform()
        dimmed = ["dim" in (line.get_attribute("class") or "").split() for line in lines]
        assert dimmed == [i != 1 for i in range(len(lines))]
        heading = chart.find_element(By.XPATH, "../h3")  # leaving it (for no line) shows every line again
        ActionChains(driver).move_to_element(heading).perform()
        assert not any("dim" in (line.get_attribute("class") or "").split() for line in lines)


@pytest.mark.browser
@browser
def test_pending_failed_flagged_sensors_rounds_history_and_details(driver: WebDriver, tmp_path: Path):
    from selenium.webdriver.common.by import By

    b = rich_board()
    ranking = rank_board(b)
    load(driver, tmp_path, board_html([b]))

    def part(key: str) -> WebElement:
        return driver.find_element(By.CSS_SELECTOR, f"section#scftc-v1-{key}")

    # the ranked figure and the pending entry's public one, both intervals as on the markdown board
    sly = driver.find_element(By.CSS_SELECTOR, 'tr[data-name="sly"]')
    sealed = pooled_text(next(r.sealed for r in ranking.deployable if r.entry.name == "sly"))
    assert sly.find_elements(By.CSS_SELECTOR, "td.pooled")[0].get_attribute("textContent").strip() == sealed
    pending = part("pending").find_element(By.CSS_SELECTOR, 'tr[data-name="newcomer"]')
    newcomer = b.entry("newcomer")
    assert newcomer is not None and "submission 0.3" in pending.text
    assert pending.find_elements(By.CSS_SELECTOR, "td")[1].text == "2"  # its round
    public = pooled_text(pooled_settled(newcomer.public, V1.ranked_classes))
    assert pending.find_element(By.CSS_SELECTOR, "td.pooled").get_attribute("textContent").strip() == public
    assert names(driver, "section#scftc-v1-pending tr[data-name]") == ["newcomer"]
    assert part("failed").text.endswith(f"broken (submission 0.3, round 1): {FAILURE}")
    # the flag links to its explanation
    flag = sly.find_element(By.CSS_SELECTOR, "a.flag")
    assert flag.text == "public above sealed on sign, gain, gain_bias, mean"
    assert flag.get_attribute("href").endswith("#scftc-v1-flagged")
    assert "beyond chance" in part("flagged").text and "only the sealed one ranks" in part("flagged").text
    # sensor faults: every sealed entry, one heat cell per sensor fault with its interval as a tooltip
    assert names(driver, "section#scftc-v1-sensors tr[data-name]") == ["alpha", "learner", "sly", "oracle"]
    cells = part("sensors").find_elements(By.CSS_SELECTOR, 'tr[data-name="alpha"] td.heat')
    assert [c.text for c in cells] == ["0.0"] * len(V1.sensor_faults)
    assert "Wilson 95 % [0.0, 0.8]" in (cells[0].get_attribute("title") or "")
    # the class heat map of the main table carries the sealed per-class rates
    learner = driver.find_element(By.CSS_SELECTOR, 'tr[data-name="learner"]')
    assert [c.text for c in learner.find_elements(By.CSS_SELECTOR, "td.heat")] == [
        "80.0",
        "70.0",
        "40.0",
        "0.0",
    ]
    # rounds and history
    rounds = part("rounds").find_elements(By.CSS_SELECTOR, "tbody tr")
    assert len(rounds) == 2 and b.rounds[0].secret in rounds[0].text and "open" in rounds[1].text
    events = part("history").find_elements(By.CSS_SELECTOR, "li")
    assert len(events) == 20 and "entry06" in events[0].text and "entry25" in events[-1].text
    # a learned built-in's details: its training seed, and a small profile chart by class
    learner.find_element(By.CSS_SELECTOR, "button.more").click()
    details = driver.find_element(By.CSS_SELECTOR, 'tbody:has(tr[data-name="learner"]) tr.details')
    assert "seed 3; 2 seeds tried" in details.text and "built-in" in details.text
    assert len(details.find_elements(By.CSS_SELECTOR, "svg polyline.series")) == len(V1.fault_classes) + 1


def test_a_one_version_page_links_every_version_and_puts_the_ranking_first():
    """A page of one board still links the other versions (on the page of every version), and its
    ranking comes before the explanation, which is folded."""
    version = published_names()[-1]
    page = board_html([read_board(default_board_path(version), version)])
    for other in published_names():
        if other != version:
            assert f'href="index.html#{other}"' in page
    assert page.index(f'id="{version}-deployable"') < page.index('<details class="reading">')
    assert "<summary>What the numbers are, and how entries rank</summary>" in page
