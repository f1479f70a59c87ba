"""The youBot Monitor in a real browser against the real demo.

``scart run composites/youbot/youbot.composite --ns 127.0.0.1:<free port>`` runs as a
subprocess (data-flow driver, SCA proxy, Locomotor, monitor); Debian's chromium, headless,
driven by playwright, opens the URL it printed. Screenshots of every tab go to
``test-artifacts/youbot-*.png`` (gitignored). No sleeps: playwright's auto-waiting
``expect`` and ``wait_for_function``, each with a timeout.
"""

from __future__ import annotations

import re
import signal
from collections.abc import Iterator

import pytest
from support.browser import BrowserPage, expect, needs_chromium, open_page
from support.youbot import Demo, post_json, start_serving

from locomotor import POSES
from youbot_model import JOINT_LIMITS

pytestmark = needs_chromium
TIMEOUT_MS = 20_000


class Session(BrowserPage):
    """The demo process, the page and the page's console errors."""

    prefix = "youbot"

    def __init__(self, demo: Demo, page: object, errors: list[str]) -> None:
        super().__init__(page, errors, TIMEOUT_MS)
        self.demo = demo


@pytest.fixture(scope="module")
def session() -> Iterator[Session]:
    demo = start_serving("youbot.composite")
    try:
        with open_page(demo.monitor_url(), TIMEOUT_MS) as (page, errors):
            yield Session(demo, page, errors)
    finally:
        code = demo.stop(signal.SIGINT)
        assert code == 0, demo.output()


def test_global_table_fills_and_updates(session: Session) -> None:
    page = session.page
    expect(page.locator("#tab-global")).to_have_attribute("aria-selected", "true")
    for cell in ("pos-0", "pos-4", "vel-2", "cur-1", "temp-3"):
        expect(page.locator(f"#{cell}")).to_have_text(re.compile(r"^-?\d+\.\d+$"))
    seq = int(page.locator("#sample-seq").inner_text())
    session.wait("s => Number(document.getElementById('sample-seq').textContent) > s + 20", seq)
    expect(page.locator("#conn-indicator")).to_have_attribute("data-state", "live")
    expect(page.locator("#driver-state")).to_have_text("RUNNING")
    expect(page.locator("#set-period")).to_contain_text("10.0 ms")
    expect(page.locator("#flags-0")).to_have_text("ok")
    # the driver runs at 10 ms: the measured rate (sample timestamps) reads ~100 Hz
    session.wait("() => Math.abs(Number(document.getElementById('measured-rate').dataset.value) - 100) < 15")
    session.wait("() => Number(document.getElementById('sample-age').dataset.value) < 0.5")
    session.wait("() => Number(document.getElementById('refresh-count').textContent) > 50")
    session.shot("global")
    assert session.errors == []


def test_joint_tab_chart_advances(session: Session) -> None:
    page = session.page
    page.click("#tab-joint-2")
    expect(page.locator("#chart-j2")).to_be_visible()
    assert "tab=joint-2" in page.url
    points = "() => { const d = document.getElementById('chart-j2').data; return d ? d[0].x.length : 0; }"
    session.wait(f"() => ({points})() > 5")
    n = page.evaluate(points)
    session.wait(f"n => ({points})() >= n + 20", n)
    session.shot("joint-2")


def test_period_set_and_measured_rate_follows(session: Session) -> None:
    page = session.page
    page.click("#tab-global")
    page.fill("#period-input", "50")  # ms
    page.click("#period-apply")
    expect(page.locator("#period-result")).to_have_attribute("data-ok", "true")
    expect(page.locator("#period-result")).to_contain_text("accepted 0.05 s")
    expect(page.locator("#set-period")).to_contain_text("50.0 ms")
    session.wait("() => Math.abs(Number(document.getElementById('measured-rate').dataset.value) - 20) < 3")
    session.shot("period-50ms")

    page.fill("#period-input", "2000")  # the driver refuses > 1 s and says why
    page.click("#period-apply")
    expect(page.locator("#period-result")).to_have_attribute("data-ok", "false")
    expect(page.locator("#period-result")).to_contain_text("2000 ms refused: the period must be between 1 ms and 1000 ms")

    page.fill("#period-input", "0.05")  # seconds typed into the ms field: refused in the user's unit
    page.click("#period-apply")
    expect(page.locator("#period-result")).to_contain_text("0.05 ms refused")
    expect(page.locator("#set-period")).to_contain_text("50.0 ms")

    page.fill("#period-input", "10")
    page.click("#period-apply")
    expect(page.locator("#period-result")).to_have_attribute("data-ok", "true")
    session.wait("() => Math.abs(Number(document.getElementById('measured-rate').dataset.value) - 100) < 15")


def test_pose_sent_and_positions_converge(session: Session) -> None:
    page = session.page
    page.click("#tab-global")
    expect(page.locator("#pose-select option")).to_have_count(len(POSES))
    page.select_option("#pose-select", "candle")
    page.click("#pose-go")
    expect(page.locator("#pose-result")).to_have_text(re.compile(r"^(moving to|at) candle$"))  # may be there already
    log = page.locator("#event-log")
    expect(log.locator("li[data-name='busy']").first).to_contain_text("moving to candle")
    session.wait(
        """t => t.every((v, i) =>
             Math.abs(Number(document.getElementById('pos-' + i).dataset.value) - v) < 0.02)""",
        POSES["candle"],
    )
    expect(log.locator("li[data-name='reached']").first).to_contain_text("candle")
    expect(page.locator("#arm-state")).to_have_text("idle")
    expect(page.locator("#pose-result")).to_have_text("at candle")  # how the move ended
    expect(page.locator("#pose-result")).to_have_attribute("data-ok", "true")
    session.shot("pose-candle")
    # a move started elsewhere (another page, a script): the old outcome does not stay
    post_json(session.demo.monitor_url() + "api/pose", {"pose": "home"})
    expect(page.locator("#pose-result")).to_have_text("moving to home")
    expect(page.locator("#pose-result")).to_have_text("at home", timeout=30_000)


# Every tick label of joint 3's time axis is a local wall-clock time of the last minute.
WALL_CLOCK_TICKS = """() => {
  const ticks = [...document.querySelectorAll('#chart-j3 .xtick text')].map((t) => t.textContent);
  if (!ticks.length || !ticks.every((t) => /^\\d\\d:\\d\\d:\\d\\d$/.test(t))) return false;
  const n = new Date();
  const now = n.getHours() * 3600 + n.getMinutes() * 60 + n.getSeconds();
  return ticks.every((t) => {
    const [h, m, s] = t.split(':').map(Number);
    const behind = (now - (h * 3600 + m * 60 + s) + 86400) % 86400;
    return behind <= 65 || behind >= 86400 - 3;
  });
}"""


def test_position_chart_shows_wall_clock_set_point_and_limits(session: Session) -> None:
    """The time axis reads the local time of day; the joint's set-point (a dashed step line)
    follows a pose sent, and its position limits are drawn on the position chart."""
    page = session.page
    page.click("#tab-joint-3")
    session.wait("() => { const d = document.getElementById('chart-j3').data; return d && d[0].x.length > 5; }")
    assert page.evaluate("document.getElementById('chart-j3').layout.xaxis.type") == "date"
    session.wait(WALL_CLOCK_TICKS)
    limits = page.evaluate("document.getElementById('chart-j3').layout.shapes.map((s) => s.y0)")
    assert sorted(limits) == sorted(JOINT_LIMITS[2])
    assert page.locator("#chart-j3 .shapelayer path").count() >= 2  # drawn, not only declared

    post_json(session.demo.monitor_url() + "api/pose", {"pose": "folded"})
    setpoint = "() => { const d = document.getElementById('chart-j3').data[4]; return d.y[d.y.length - 1]; }"
    assert page.evaluate("document.getElementById('chart-j3').data[4].name") == "set-point"
    session.wait(f"t => Math.abs(({setpoint})() - t) < 1e-6", POSES["folded"][2])
    session.shot("joint-3-setpoint")


def test_bad_url_hash_rewritten_to_the_view_shown(session: Session) -> None:
    page = session.page
    page.click("#tab-global")
    page.evaluate("location.hash = 'tab=bogus&window=7'")
    session.wait("() => location.hash.includes('tab=global') && !location.hash.includes('window=7')")
    assert re.fullmatch(r"#tab=global&window=(5|10|30|60)", page.evaluate("location.hash"))


def test_error_flags_shown_by_name(session: Session) -> None:
    """A set-point beyond joint 1's limit is clipped by the driver: POSITION_LIMIT shows at once."""
    from dataflow.remote import connect

    page = session.page
    page.click("#tab-global")
    with connect(session.demo.ns) as system:  # as `scart write youBotDriver.commands ...` would
        driver = system.component("youBotDriver")
        driver.write("commands", [3.5, 0.0, 0.0, 0.0, 0.0])
        expect(page.locator("#flags-0")).to_contain_text("POSITION_LIMIT")
        expect(page.locator("#flags-1")).to_have_text("ok")
        session.shot("error-flags")
        driver.write("commands", [0.0, 0.0, 0.0, 0.0, 0.0])
        expect(page.locator("#flags-0")).to_have_text("ok")


def test_overlapping_joints_stay_apart_and_stale_values_are_greyed(session: Session) -> None:
    """Each joint's overview line has a dash of its own (and a legend entry to toggle it);
    while the driver is stopped, the table's values are greyed with their age."""
    from dataflow.remote import connect

    page = session.page
    page.click("#tab-global")
    session.wait("() => { const d = document.getElementById('chart-overview').data; return d && d.length === 5; }")
    dashes = page.evaluate("document.getElementById('chart-overview').data.map(t => t.line.dash)")
    assert len(set(dashes)) == 5, dashes
    assert page.evaluate("document.getElementById('chart-overview').layout.showlegend") is True
    table = page.locator("#joint-table")
    expect(table).not_to_have_class(re.compile(r"\bstale\b"))
    with connect(session.demo.ns) as system:  # as `scart state youBotDriver stop` would
        driver = system.component("youBotDriver")
        assert driver.stop()
        try:
            expect(table).to_have_class(re.compile(r"\bstale\b"))
            expect(table).to_have_attribute("title", re.compile(r"^last values, \d+\.\d s old$"))
            session.shot("stale")
        finally:
            assert driver.start()
    expect(table).not_to_have_class(re.compile(r"\bstale\b"))


def test_a_page_opened_later_starts_with_the_recent_history(session: Session) -> None:
    """The server keeps the last minute: a second page's chart is full at once, not empty
    (live updates alone would bring at most ~25 points a second)."""
    page = session.page.context.browser.new_context().new_page()  # a second page of the same browser
    try:
        page.goto(session.demo.monitor_url())
        page.wait_for_function(
            "() => { const d = document.getElementById('chart-overview').data; return d && d[0].x.length > 100; }",
            timeout=3000)
    finally:
        page.context.close()


def test_screenshot_every_tab(session: Session) -> None:
    page = session.page
    saved = []
    for j in range(1, 6):
        page.click(f"#tab-joint-{j}")
        session.wait("j => { const d = document.getElementById('chart-j' + j).data; return d && d[0].x.length > 20; }", j)
        saved.append(session.shot(f"joint-{j}"))
    page.click("#tab-global")
    expect(page.locator("#panel-global")).to_be_visible()
    saved.append(session.shot("global-final"))
    assert all(p.stat().st_size > 10_000 for p in saved)
    assert session.errors == []
