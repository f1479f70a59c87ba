"""The youBot Monitor in a real browser: Debian's chromium, headless, driven by playwright.

The HTTP server and the browser are real; the driver side is `SyntheticArm` (a feeder thread
publishing statuses at 50 Hz and a fake backend). Screenshots of every tab go to
``test-artifacts/`` (gitignored). No sleeps: playwright's auto-waiting `expect` and
`wait_for_function`, each with a timeout.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

import pytest
from support.browser import BrowserPage, expect, needs_chromium, open_page

from scart_monitor import MonitorServer
from scart_monitor.demo import POSES, SyntheticArm

pytestmark = needs_chromium
TIMEOUT_MS = 30_000


class Monitor(BrowserPage):
    """What the tests share: the server, the synthetic arm, the page and its console errors."""

    prefix = "monitor"

    def __init__(self, server: MonitorServer, arm: SyntheticArm, page: object, errors: list[str]) -> None:
        super().__init__(page, errors, TIMEOUT_MS)
        self.server, self.arm = server, arm


@pytest.fixture(scope="module")
def monitor() -> Iterator[Monitor]:
    arm = SyntheticArm(period=0.02, seed=1)
    server = MonitorServer(arm)
    try:
        server.start()
        arm.start(server)
        with open_page(server.url, TIMEOUT_MS) as (page, errors):
            yield Monitor(server, arm, page, errors)
    finally:
        arm.stop()
        server.stop()


def test_global_table_fills_and_updates(monitor: Monitor) -> None:
    page = monitor.page
    expect(page.locator("#tab-global")).to_have_attribute("aria-selected", "true")
    expect(page.locator("#pos-0")).not_to_have_text("—")
    for cell in ("pos-4", "vel-2", "cur-1", "temp-3"):
        expect(page.locator(f"#{cell}")).to_have_text(re.compile(r"^-?\d+\.\d+$"))
    seq = int(page.locator("#sample-seq").inner_text())
    monitor.wait("s => Number(document.getElementById('sample-seq').textContent) > s + 10", seq)
    expect(page.locator("#conn-indicator")).to_have_attribute("data-state", "live")
    expect(page.locator("#driver-state")).to_have_text("RUNNING")
    expect(page.locator("#flags-4")).to_contain_text("OVER_TEMPERATURE")  # joint 5 runs hot
    expect(page.locator("#flags-0")).to_have_text("ok")
    # measured rate (server-side, from sample timestamps) matches the 20 ms feeder
    monitor.wait("() => Math.abs(Number(document.getElementById('measured-rate').dataset.value) - 50) < 5")
    monitor.wait("() => Number(document.getElementById('sample-age').dataset.value) < 1")
    monitor.wait("() => Number(document.getElementById('refresh-count').textContent) > 10")
    monitor.shot("global")
    assert monitor.errors == []


def test_joint_tab_chart_advances_pauses_and_clears(monitor: Monitor) -> None:
    page = monitor.page
    page.click("#tab-joint-2")
    expect(page.locator("#panel-joint")).to_be_visible()
    expect(page.locator("#chart-j2")).to_be_visible()
    expect(page.locator("#chart-j1")).to_be_hidden()
    assert "tab=joint-2" in page.url
    points = "() => { const d = document.getElementById('chart-j2').data; return d ? d[0].x.length : 0; }"
    monitor.wait(f"() => ({points})() > 5")
    n = monitor.js(points)
    monitor.wait(f"n => ({points})() >= n + 10", n)
    assert monitor.js("document.getElementById('chart-j2').data.length") == 5  # pos, vel, cur, temp, set-point

    page.click("#pause")
    expect(page.locator("#pause")).to_have_text("Resume")
    frozen = monitor.js(points)
    received = int(page.locator("#sample-count").inner_text())
    monitor.wait("r => Number(document.getElementById('sample-count').textContent) > r + 15", received)
    assert monitor.js(points) == frozen  # samples kept coming, the chart stood still
    page.click("#pause")
    expect(page.locator("#pause")).to_have_text("Pause")
    monitor.wait(f"n => ({points})() > n + 10", frozen)  # resumed with what came meanwhile

    before = monitor.js(points)
    page.click("#clear")
    monitor.wait(f"n => ({points})() < n", before)
    monitor.wait(f"() => ({points})() > 3")  # and it fills again


def test_window_is_kept_in_the_url_and_restored(monitor: Monitor) -> None:
    page = monitor.page
    page.click("#tab-joint-3")
    page.select_option("#window-select", "30")
    expect(page).to_have_url(re.compile(r"#tab=joint-3&window=30$"))
    # a wall-clock axis: Plotly may keep the range as epoch ms or turn it into date strings
    span = """() => { const ms = (v) => typeof v === 'number' ? v : Date.parse(String(v).replace(' ', 'T'));
                      const r = document.getElementById('chart-j3').layout.xaxis.range; return (ms(r[1]) - ms(r[0])) / 1000; }"""
    monitor.wait(f"() => Math.abs(({span})() - 30) < 1e-3")

    page.reload()
    expect(page.locator("#tab-joint-3")).to_have_attribute("aria-selected", "true")
    expect(page.locator("#window-select")).to_have_value("30")
    expect(page.locator("#chart-j3")).to_be_visible()
    monitor.wait("() => { const d = document.getElementById('chart-j3').data; return d && d[0].x.length > 3; }")
    monitor.wait(f"() => Math.abs(({span})() - 30) < 1e-3")
    page.select_option("#window-select", "10")
    expect(page).to_have_url(re.compile(r"window=10$"))


def test_period_control_shows_the_answer_and_the_rate_follows(monitor: Monitor) -> None:
    page = monitor.page
    page.click("#tab-global")
    page.fill("#period-input", "40")
    page.click("#period-apply")
    expect(page.locator("#period-result")).to_have_text("driver period set to 40 ms")
    expect(page.locator("#period-result")).to_have_attribute("data-ok", "true")
    expect(page.locator("#set-period")).to_contain_text("40.0 ms")
    monitor.wait("() => Math.abs(Number(document.getElementById('measured-rate').dataset.value) - 25) < 2.5")

    page.fill("#period-input", "0.5")
    page.click("#period-apply")
    expect(page.locator("#period-result")).to_have_attribute("data-ok", "false")
    expect(page.locator("#period-result")).to_contain_text("must be between 2 ms and 1 s")

    page.fill("#period-input", "20")
    page.click("#period-apply")
    expect(page.locator("#period-result")).to_have_text("driver period set to 20 ms")
    monitor.wait("() => Math.abs(Number(document.getElementById('measured-rate').dataset.value) - 50) < 5")
    assert monitor.arm.sent == []  # no pose sent by the period control


def test_pose_control_moves_the_arm_and_events_show(monitor: Monitor) -> None:
    page = monitor.page
    expect(page.locator("#pose-select option")).to_have_count(len(POSES))
    page.select_option("#pose-select", "candle")
    page.click("#pose-go")
    expect(page.locator("#pose-result")).to_have_text("moving to candle")
    assert monitor.arm.sent == ["candle"]
    log = page.locator("#event-log")
    expect(log.locator("li[data-name='busy']").first).to_contain_text("moving to candle")
    expect(log.locator("li[data-name='reached']").first).to_contain_text("candle")
    expect(log.locator("li[data-name='idle']").first).to_be_visible()
    expect(page.locator("#arm-state")).to_have_text("idle")
    target = POSES["candle"]
    monitor.wait(
        """t => t.every((v, i) =>
             Math.abs(Number(document.getElementById('pos-' + i).dataset.value) - v) < 0.01)""",
        target,
    )
    # refresh is counted, never listed row by row
    assert log.locator("li[data-name='refresh']").count() == 0


def test_screenshot_every_tab(monitor: Monitor) -> None:
    page = monitor.page
    saved = []
    for j in range(1, 6):
        page.click(f"#tab-joint-{j}")
        monitor.wait(
            "j => { const d = document.getElementById('chart-j' + j).data; return d && d[0].x.length > 20; }", j
        )
        saved.append(monitor.shot(f"joint-{j}"))
    page.click("#tab-global")
    expect(page.locator("#panel-global")).to_be_visible()
    saved.append(monitor.shot("global"))
    assert all(p.stat().st_size > 10_000 for p in saved)
    assert monitor.errors == []


def test_token_mode_page_sends_the_token_and_cannot_be_framed(monitor: Monitor) -> None:
    """Token mode: the page opened from `page_url` commands, one opened without the token is
    refused; and chromium refuses to show the monitor in a frame (X-Frame-Options, CSP).
    A second context of the module's browser (one playwright per thread)."""
    arm = SyntheticArm(period=0.02, seed=2)  # backend only: its feeder is not started
    server = MonitorServer(arm, token="per-launch-token")
    context = monitor.page.context.browser.new_context()
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.on("console", lambda msg: errors.append(msg.text) if msg.type == "error" else None)
    try:
        server.start()
        page.goto(server.page_url)
        page.fill("#period-input", "40")
        page.click("#period-apply")
        expect(page.locator("#period-result")).to_have_text("driver period set to 40 ms")
        expect(page).to_have_url(re.compile(r"\?token=per-launch-token#tab=global"))  # kept in the URL
        assert errors == []  # the page runs under its Content-Security-Policy

        page.goto(server.url)  # no token in the URL: the page works, its commands do not
        page.fill("#period-input", "50")
        page.click("#period-apply")
        expect(page.locator("#period-result")).to_contain_text("missing or wrong control token")
        expect(page.locator("#period-result")).to_have_attribute("data-ok", "false")

        page.goto("about:blank")
        page.set_content(f'<iframe id="f" src="{server.url}"></iframe>')
        page.wait_for_function("() => window.frames.length === 1", timeout=TIMEOUT_MS)
        child = page.frames[1]
        child.wait_for_load_state(timeout=TIMEOUT_MS)
        assert child.url.startswith("chrome-error://")  # blocked: not the monitor page
        assert arm.sent == []
    finally:
        context.close()
        server.stop()


def test_long_event_text_wraps_instead_of_being_cut(monitor: Monitor) -> None:
    """``joint 2: UNDER_VOLTAGE set`` and ``... cleared`` must both read to the end: the
    event text wraps within the log, it is never cut with an ellipsis."""
    page = monitor.page
    detail = "joint 2: UNDER_VOLTAGE " + "and a long explanation of what happened " * 6 + "cleared"
    monitor.server.publish_event("error", detail)
    row = page.locator("#event-log li[data-name='error'] .d", has_text="cleared").first
    expect(row).to_be_visible()
    fits = row.evaluate("el => el.scrollWidth <= el.clientWidth + 1 && getComputedStyle(el).textOverflow !== 'ellipsis'")
    lines = row.evaluate("el => Math.round(el.getBoundingClientRect().height / parseFloat(getComputedStyle(el).lineHeight || 16))")
    assert fits and lines >= 2, lines
    assert monitor.errors == []


def test_connection_indicator_follows_data_driver_and_server(monitor: Monitor) -> None:
    """Runs last: it stops the feeder and the server."""
    page = monitor.page
    page.click("#tab-global")
    expect(page.locator("#conn-indicator")).to_have_attribute("data-state", "live")
    monitor.arm.stop()  # samples stop: the age grows (server heartbeats), the rate drops to 0
    expect(page.locator("#conn-indicator")).to_have_attribute("data-state", "stale")
    monitor.wait("() => Number(document.getElementById('measured-rate').dataset.value) === 0")
    expect(page.locator("#age-pill")).to_have_class(re.compile(r"\bwarn\b"))
    monitor.server.set_driver_info("UNREACHABLE", 0.02, False)
    expect(page.locator("#conn-indicator")).to_have_attribute("data-state", "driver-offline")
    expect(page.locator("#event-log li[data-name='disconnected']").first).to_be_visible()
    monitor.server.stop()
    expect(page.locator("#conn-indicator")).to_have_attribute("data-state", "server-lost")
    expect(page.locator("#conn-text")).to_have_text("monitor unreachable")

