// youBot Monitor page. Data comes from the server's SSE stream (/events); the page measures
// nothing itself (age, rate and error flag names are computed by the server).
"use strict";

(() => {
  const JOINTS = 5;
  const WINDOWS = [5, 10, 30, 60];
  const MAX_POINTS = 2000;            // per trace: 60 s at the server's 25 updates/s, with margin
  const MAX_LOG_ROWS = 100;
  const CHART_MS = 100;               // charts redraw at most 10 times/s (the table follows every update)
  const STALE_S = 1.0;
  const FIELDS = [
    { key: "position", label: "position", unit: "rad", color: "#2f81f7", digits: 3 },
    { key: "velocity", label: "velocity", unit: "rad/s", color: "#8250df", digits: 3 },
    { key: "current", label: "current", unit: "A", color: "#d4a017", digits: 2 },
    { key: "temperature", label: "temperature", unit: "°C", color: "#d73a49", digits: 1 },
  ];
  const CELL = { position: "pos", velocity: "vel", current: "cur", temperature: "temp" };
  const JOINT_COLORS = ["#2f81f7", "#8250df", "#d4a017", "#1f9d55", "#d73a49"];
  const JOINT_DASHES = ["solid", "dash", "dot", "dashdot", "longdash"];   // joints that overlap stay apart
  const SETPOINT = FIELDS.length;    // buffers' series after the fields: the position set-point
  const SETPOINT_COLOR = "#57606a";
  const LIMIT_COLOR = "#d73a49";
  // The time axis is wall-clock, in the browser's time zone: Plotly draws epoch numbers as UTC.
  const TZ_MS = new Date().getTimezoneOffset() * 60000;
  const toX = (stamp) => stamp * 1000 - TZ_MS;
  const PLOT_CONFIG = { responsive: true, displaylogo: false, modeBarButtonsToRemove: ["lasso2d", "select2d"] };

  const RECONNECT_MS = 5000;          // after the server refused the stream (503: too many streams)
  // Token mode: the monitor printed http://HOST:PORT/?token=...; commands carry it (GETs need none).
  const TOKEN = new URLSearchParams(location.search).get("token");

  const $ = (id) => document.getElementById(id);
  const view = { tab: "global", window: 10, paused: false };
  const buffers = Array.from({ length: JOINTS }, () => ({ x: [], y: [...FIELDS, "setpoint"].map(() => []) }));
  let jointLimits = [];               // [lo, hi] per joint (rad), from /api/history
  const plotted = new Set();          // charts drawn (0: overview, 1-5: joints)
  const drawnUpTo = {};               // chart → x of the last point it shows
  let lastSeq = null;
  let lastStamp = null;
  let streamOpen = false;
  let lastMsg = null;
  let periodTouched = false;

  // ---------------------------------------------------------------- view state in the URL
  function readHash() {
    const params = new URLSearchParams(location.hash.slice(1));
    const tab = params.get("tab");
    if (tab === "global" || /^joint-[1-5]$/.test(tab || "")) view.tab = tab;
    const win = Number(params.get("window"));
    if (WINDOWS.includes(win)) view.window = win;
  }
  function writeHash() {
    const params = new URLSearchParams({ tab: view.tab, window: String(view.window) });
    history.replaceState(null, "", "#" + params.toString());
  }
  const activeJoint = () => (view.tab.startsWith("joint-") ? Number(view.tab.slice(6)) : 0);

  // ---------------------------------------------------------------- tabs
  function showTab(tab) {
    view.tab = tab;
    document.querySelectorAll(".tab").forEach((b) =>
      b.setAttribute("aria-selected", String(b.dataset.tab === tab)));
    const j = activeJoint();
    $("panel-global").hidden = j !== 0;
    $("panel-joint").hidden = j === 0;
    if (j) {
      $("joint-title").textContent = "Joint " + j;
      for (let k = 1; k <= JOINTS; k++) $("chart-j" + k).hidden = k !== j;
      redraw(j);
    } else {
      drawOverview();
    }
    writeHash();
  }

  // ---------------------------------------------------------------- table
  function buildTable() {
    const body = $("joint-rows");
    for (let i = 0; i < JOINTS; i++) {
      const tr = document.createElement("tr");
      tr.id = "row-" + i;
      const th = document.createElement("th");
      const a = document.createElement("a");
      a.href = "#";
      a.textContent = "J" + (i + 1);
      a.title = "open the charts of joint " + (i + 1);
      a.addEventListener("click", (e) => { e.preventDefault(); showTab("joint-" + (i + 1)); });
      th.appendChild(a);
      tr.appendChild(th);
      for (const f of FIELDS) {
        const td = document.createElement("td");
        td.id = CELL[f.key] + "-" + i;
        td.className = "num";
        td.textContent = "—";
        tr.appendChild(td);
      }
      const flags = document.createElement("td");
      flags.id = "flags-" + i;
      tr.appendChild(flags);
      body.appendChild(tr);
    }
  }

  // Fixed digits, without a "-0.000" for tiny negative values.
  function fmt(v, digits) {
    if (typeof v !== "number" || !Number.isFinite(v)) return "—";
    const text = v.toFixed(digits);
    return /^-0\.?0*$/.test(text) ? text.slice(1) : text;
  }

  // Live values of the joint whose charts are shown, next to its chart controls.
  function fillReadout(joints, flagNames) {
    const j = activeJoint();
    const joint = j ? joints[j - 1] : null;
    if (!joint) return;
    const parts = FIELDS.map((f, k) => {
      const v = joint[f.key];
      const span = document.createElement("span");
      span.append((k ? " · " : "") + CELL[f.key] + " ");
      const b = document.createElement("b");
      b.textContent = fmt(v, f.digits);
      span.append(b, " " + f.unit);
      return span;
    });
    const flags = (flagNames[j - 1] || []).map((n) => {
      const s = document.createElement("span");
      s.className = "flag";
      s.textContent = n;
      return s;
    });
    $("joint-readout").replaceChildren(...parts, ...flags);
  }

  function fillTable(status, flagNames) {
    const joints = Array.isArray(status.joints) ? status.joints : [];
    fillReadout(joints, flagNames);
    for (let i = 0; i < JOINTS; i++) {
      const joint = joints[i] || {};
      for (const f of FIELDS) {
        const cell = $(CELL[f.key] + "-" + i);
        const v = joint[f.key];
        cell.textContent = fmt(v, f.digits);
        cell.dataset.value = typeof v === "number" ? String(v) : "";
      }
      const names = flagNames[i] || [];
      const cell = $("flags-" + i);
      const key = names.join(",");
      if (cell.dataset.value !== key || !cell.firstChild) {
        cell.dataset.value = key;
        cell.replaceChildren(...(names.length ? names : ["ok"]).map((n) => {
          const s = document.createElement("span");
          s.className = names.length ? "flag" : "flag none";
          s.textContent = n;
          return s;
        }));
      }
    }
  }

  // ---------------------------------------------------------------- charts
  function baseLayout(xEnd) {
    return {
      margin: { l: 58, r: 12, t: 8, b: 32 },
      showlegend: false,
      paper_bgcolor: "#fff",
      plot_bgcolor: "#fff",
      font: { family: "system-ui, sans-serif", size: 11, color: "#444c56" },
      xaxis: {
        type: "date", range: [xEnd - view.window * 1000, xEnd], title: { text: "time", standoff: 4 },
        tickformat: "%H:%M:%S", hoverformat: "%H:%M:%S.%L", gridcolor: "#eceff2", zeroline: false,
      },
      datarevision: Date.now(),
    };
  }

  // Dotted lines at joint j's position limits, on its position chart.
  function limitShapes(j) {
    const lim = jointLimits[j - 1];
    if (!Array.isArray(lim)) return [];
    return lim.map((y) => ({
      type: "line", xref: "paper", x0: 0, x1: 1, yref: "y", y0: y, y1: y, name: "limit",
      line: { color: LIMIT_COLOR, width: 1, dash: "dot" },
    }));
  }

  function layoutFor(j, xEnd) {
    const n = FIELDS.length;
    const gap = 0.04;
    const h = (1 - gap * (n - 1)) / n;
    const layout = baseLayout(xEnd);
    layout.xaxis.anchor = "y" + n;
    FIELDS.forEach((f, k) => {
      const top = 1 - k * (h + gap);
      layout["yaxis" + (k ? k + 1 : "")] = {
        domain: [top - h, top], title: { text: f.label + " (" + f.unit + ")", font: { size: 10 } },
        gridcolor: "#eceff2", zeroline: false, automargin: true,
      };
    });
    layout.shapes = limitShapes(j);
    return layout;
  }

  function tracesFor(j) {
    const buf = buffers[j - 1];
    const traces = FIELDS.map((f, k) => ({
      type: "scatter", mode: "lines", name: f.label,
      x: buf.x.slice(), y: buf.y[k].slice(), xaxis: "x", yaxis: "y" + (k ? k + 1 : ""),
      line: { color: f.color, width: 1.5 }, hovertemplate: "%{y:." + f.digits + "f} " + f.unit + "<extra></extra>",
    }));
    traces.push({   // where the joint is told to go, under its position
      type: "scatter", mode: "lines", name: "set-point", x: buf.x.slice(), y: buf.y[SETPOINT].slice(),
      xaxis: "x", yaxis: "y", line: { color: SETPOINT_COLOR, width: 1, dash: "dash", shape: "hv" },
      hovertemplate: "set-point %{y:.3f} rad<extra></extra>",
    });
    return traces;
  }

  // x of the newest sample (charts scroll together, even right after a clear); now before any
  function xEndOf() {
    return toX(lastStamp !== null ? lastStamp : Date.now() / 1000);
  }

  function redraw(j) {
    if (!window.Plotly || !j) return;
    const div = $("chart-j" + j);
    Plotly.react(div, tracesFor(j), layoutFor(j, xEndOf()), PLOT_CONFIG);
    plotted.add(j);
    drawnUpTo[j] = lastX(buffers[j - 1]);
    $("point-count").textContent = String(buffers[j - 1].x.length);
  }

  function drawOverview() {
    if (!window.Plotly) return;
    const layout = baseLayout(xEndOf());
    layout.showlegend = true;
    layout.legend = { orientation: "h", x: 0, y: 1.0, yanchor: "bottom", font: { size: 11 } };
    layout.margin.t = 24;
    layout.yaxis = { title: { text: "position (rad)", font: { size: 10 } }, gridcolor: "#eceff2", zeroline: false };
    const traces = buffers.map((buf, i) => ({
      type: "scatter", mode: "lines", name: "J" + (i + 1), x: buf.x.slice(), y: buf.y[0].slice(),
      line: { color: JOINT_COLORS[i], width: 1.5, dash: JOINT_DASHES[i] },
      hovertemplate: "J" + (i + 1) + " %{y:.3f} rad<extra></extra>",
    }));
    Plotly.react($("chart-overview"), traces, layout, PLOT_CONFIG);
    plotted.add(0);
    drawnUpTo[0] = Math.max(...buffers.map(lastX));
    $("overview-window").textContent = view.window + " s";
  }

  const lastX = (buf) => (buf.x.length ? buf.x[buf.x.length - 1] : -Infinity);

  // Points of ``buf`` (x and the y series ``ks``) newer than ``after``.
  function newer(buf, after, ks) {
    let from = buf.x.length;
    while (from > 0 && buf.x[from - 1] > after) from--;
    return { x: buf.x.slice(from), ys: ks.map((k) => buf.y[k].slice(from)) };
  }

  // Append per-trace points; the range is set first so extendTraces' one redraw scrolls too.
  function extendChart(div, xs, ys) {
    const end = xEndOf();
    div.layout.xaxis.range = [end - view.window * 1000, end];
    Plotly.extendTraces(div, { x: xs, y: ys }, ys.map((_, k) => k), MAX_POINTS);
  }

  // Bring the visible chart up to date with the buffers (runs every CHART_MS).
  function flushCharts() {
    if (!window.Plotly) return;
    const j = activeJoint();
    if (j && !view.paused) {
      if (!plotted.has(j)) { redraw(j); return; }
      const pts = newer(buffers[j - 1], drawnUpTo[j], buffers[j - 1].y.map((_, k) => k));
      if (!pts.x.length) return;
      const div = $("chart-j" + j);
      extendChart(div, pts.ys.map(() => pts.x), pts.ys);
      drawnUpTo[j] = pts.x[pts.x.length - 1];
      $("point-count").textContent = String(div.data[0].x.length);
    } else if (!j) {
      if (!plotted.has(0)) { drawOverview(); return; }
      const pts = buffers.map((buf) => newer(buf, drawnUpTo[0], [0]));
      if (!pts.some((p) => p.x.length)) return;
      extendChart($("chart-overview"), pts.map((p) => p.x), pts.map((p) => p.ys[0]));
      drawnUpTo[0] = Math.max(...buffers.map(lastX));
    }
  }

  function record(status) {
    const stamp = typeof status.timestamp === "number" ? status.timestamp : null;
    if (stamp === null) return;
    if (lastStamp !== null && stamp < lastStamp) {        // the source's clock went back: start over
      buffers.forEach((b) => { b.x.length = 0; b.y.forEach((y) => (y.length = 0)); });
      plotted.clear();                                    // the next flush redraws from scratch
    }
    lastStamp = stamp;
    const x = toX(stamp);
    const joints = Array.isArray(status.joints) ? status.joints : [];
    joints.slice(0, JOINTS).forEach((joint, i) => {
      const buf = buffers[i];
      const values = [...FIELDS.map((f) => f.key), "setpoint"].map((key) => (typeof joint[key] === "number" ? joint[key] : null));
      buf.x.push(x);
      values.forEach((v, k) => buf.y[k].push(v));
      if (buf.x.length > MAX_POINTS) {
        const drop = buf.x.length - MAX_POINTS;
        buf.x.splice(0, drop);
        buf.y.forEach((y) => y.splice(0, drop));
      }
    });
  }

  // ---------------------------------------------------------------- header & events
  function fmtPeriod(p) {
    if (typeof p !== "number" || !(p > 0)) return "—";
    return (p * 1000).toFixed(p < 0.01 ? 2 : 1) + " ms · " + (1 / p).toFixed(1) + " Hz";
  }

  function updateHeader(msg) {
    const d = msg.driver || {};
    $("driver-state").textContent = d.connected ? (d.state || "—") : "offline";
    $("set-period").textContent = fmtPeriod(d.period);
    const rate = $("measured-rate");
    rate.textContent = msg.rate.toFixed(1) + " Hz";
    rate.dataset.value = String(msg.rate);
    const expected = typeof d.period === "number" && d.period > 0 ? 1 / d.period : null;
    $("rate-pill").classList.toggle("warn", expected !== null && Math.abs(msg.rate - expected) > 0.1 * expected);
    const age = $("sample-age");
    if (typeof msg.age === "number") {
      age.textContent = msg.age < 1 ? (msg.age * 1000).toFixed(0) + " ms" : msg.age.toFixed(1) + " s";
      age.dataset.value = String(msg.age);
    }
    $("age-pill").classList.toggle("warn", !(typeof msg.age === "number" && msg.age < STALE_S));
    const sm = msg.summary;
    if (sm && Array.isArray(sm.positions)) {
      $("arm-summary").textContent = (sm.busy ? "busy" : "idle") + " · " + sm.positions.map((p) => p.toFixed(2)).join(" ");
    }
    const gr = msg.gripper;
    if (gr && typeof gr.x === "number") {
      $("gripper").textContent = [gr.x, gr.y, gr.z].map((v) => v.toFixed(3)).join(" ") + " m";
    }
    setConn(msg);
    if (!periodTouched && document.activeElement !== $("period-input") && typeof d.period === "number") {
      $("period-input").value = String(+(d.period * 1000).toFixed(3));
    }
  }

  function setConn(msg) {
    const el = $("conn-indicator");
    let state, text;
    if (!streamOpen) { state = "server-lost"; text = "monitor unreachable"; }
    else if (!msg || !(msg.driver || {}).connected) { state = "driver-offline"; text = "driver offline"; }
    else if (!(typeof msg.age === "number" && msg.age < STALE_S)) { state = "stale"; text = "no data"; }
    else { state = "live"; text = "live"; }
    el.dataset.state = state;
    $("conn-text").textContent = text;
    // values no longer live (driver offline or stopped, or no new sample): greyed, with their age
    const d = (msg && msg.driver) || {};
    const stale = state !== "live" || (d.state && d.state !== "RUNNING");
    const table = $("joint-table");
    table.classList.toggle("stale", Boolean(stale));
    table.title = stale && msg && typeof msg.age === "number" ? "last values, " + msg.age.toFixed(1) + " s old" : "";
  }

  function addEvents(events) {
    const log = $("event-log");
    for (const ev of events) {
      const li = document.createElement("li");
      li.className = "ev-" + String(ev.name).replace(/[^a-z0-9_-]/gi, "");
      li.dataset.name = ev.name;
      const t = document.createElement("span");
      t.className = "t";
      const when = new Date(ev.time * 1000);
      t.textContent = when.toLocaleTimeString([], { hour12: false }) + "." + String(when.getMilliseconds()).padStart(3, "0");
      t.title = when.toISOString();
      const n = document.createElement("span");
      n.className = "n";
      n.textContent = ev.name;
      const dd = document.createElement("span");
      dd.className = "d";
      dd.textContent = ev.detail || "";
      dd.title = ev.detail || "";
      li.append(t, n, dd);
      log.prepend(li);
      if (ev.name === "busy" || ev.name === "idle") {
        $("arm-state").textContent = ev.name;
        $("arm-pill").dataset.state = ev.name;
      }
      if (ev.name === "busy") {   // a new move: the last outcome ("at candle") no longer holds
        const out = $("pose-result");
        delete out.dataset.ok;
        out.textContent = ev.detail || "moving";
      }
      if (ev.name === "idle" && ev.detail && ev.detail !== "arm ready") {   // why the move ended
        const out = $("pose-result");
        out.dataset.ok = String(!/not reached|superseded/.test(ev.detail));
        out.textContent = ev.detail;
      }
    }
    while (log.children.length > MAX_LOG_ROWS) log.lastElementChild.remove();
  }

  function updateRefresh(coalesced) {
    const r = (coalesced || {}).refresh;
    if (!r) return;
    $("refresh-count").textContent = String(r.count);
    $("refresh-last").textContent = "· last " + (r.age < 1 ? (r.age * 1000).toFixed(0) + " ms" : r.age.toFixed(1) + " s") + " ago";
  }

  function onUpdate(msg) {
    lastMsg = msg;
    updateHeader(msg);
    addEvents(msg.events || []);
    updateRefresh(msg.coalesced);
    $("sample-count").textContent = String(msg.samples);
    const status = msg.status;
    if (!status) return;
    $("sample-seq").textContent = status.sequence ?? "—";
    const seq = status.sequence ?? msg.version;
    if (seq === lastSeq) return;
    lastSeq = seq;
    fillTable(status, msg.flags || []);
    record(status);
  }

  // The last minute the server kept, drawn before going live (charts open with history).
  async function loadHistory() {
    try {
      const r = await fetch("/api/history", { cache: "no-store" });
      const body = await r.json();
      if (Array.isArray(body.joint_limits)) jointLimits = body.joint_limits;
      for (const status of body.statuses || []) record(status);
      plotted.clear();   // a chart drawn meanwhile is drawn again, with the history and the limits
    } catch (err) {
      console.warn("no history", err);
    }
  }

  function connect() {
    const es = new EventSource("/events");
    es.onopen = () => { streamOpen = true; setConn(lastMsg); };
    es.onerror = () => {   // EventSource retries by itself, except after an HTTP error (503): then we do
      streamOpen = false;
      setConn(lastMsg);
      if (es.readyState === EventSource.CLOSED) setTimeout(connect, RECONNECT_MS);
    };
    es.addEventListener("update", (e) => {
      streamOpen = true;
      try { onUpdate(JSON.parse(e.data)); } catch (err) { console.error("monitor update failed", err); }
    });
  }

  // ---------------------------------------------------------------- commands
  async function post(path, body, resultId, button) {
    const out = $(resultId);
    out.dataset.ok = "";
    out.textContent = "sending…";
    button.disabled = true;
    try {
      const headers = { "Content-Type": "application/json" };
      if (TOKEN) headers["X-Monitor-Token"] = TOKEN;
      const res = await fetch(path, { method: "POST", headers, body: JSON.stringify(body) });
      const answer = await res.json().catch(() => ({ ok: false, message: "HTTP " + res.status }));
      out.dataset.ok = String(Boolean(answer.ok));
      out.textContent = answer.message || (answer.ok ? "accepted" : "refused");
    } catch (err) {
      out.dataset.ok = "false";
      out.textContent = "monitor unreachable: " + err;
    } finally {
      button.disabled = false;
    }
  }

  async function loadPoses() {
    try {
      const res = await fetch("/api/poses");
      const { poses } = await res.json();
      const sel = $("pose-select");
      sel.replaceChildren(...poses.map((p) => new Option(p, p)));
      $("pose-go").disabled = poses.length === 0;
    } catch (err) {
      $("pose-result").textContent = "could not load poses: " + err;
    }
  }

  function wire() {
    document.querySelectorAll(".tab").forEach((b) => b.addEventListener("click", () => showTab(b.dataset.tab)));
    $("window-select").value = String(view.window);
    $("window-select").addEventListener("change", (e) => {
      view.window = Number(e.target.value);
      writeHash();
      const j = activeJoint();
      if (j && plotted.has(j)) Plotly.relayout($("chart-j" + j), { "xaxis.range": [xEndOf() - view.window * 1000, xEndOf()] });
    });
    $("pause").addEventListener("click", () => {
      view.paused = !view.paused;
      $("pause").setAttribute("aria-pressed", String(view.paused));
      $("pause").textContent = view.paused ? "Resume" : "Pause";
      if (!view.paused) redraw(activeJoint());
    });
    $("clear").addEventListener("click", () => {
      const j = activeJoint();
      if (!j) return;
      const b = buffers[j - 1];
      b.x.length = 0;
      b.y.forEach((y) => (y.length = 0));
      redraw(j);
    });
    $("period-input").addEventListener("input", () => { periodTouched = true; });
    $("period-form").addEventListener("submit", (e) => {
      e.preventDefault();
      const ms = Number($("period-input").value);
      if (!Number.isFinite(ms) || $("period-input").value.trim() === "") {
        $("period-result").dataset.ok = "false";
        $("period-result").textContent = "enter the period in milliseconds";
        return;
      }
      periodTouched = false;
      post("/api/period", { seconds: ms / 1000 }, "period-result", $("period-apply")).then(() => {
        const out = $("period-result");   // the driver speaks seconds; the user typed ms
        if (out.dataset.ok === "false" && /^rejected /.test(out.textContent)) {
          out.textContent = ms + " ms refused: the period must be between 1 ms and 1000 ms";
        }
      });
    });
    $("pose-form").addEventListener("submit", (e) => {
      e.preventDefault();
      const pose = $("pose-select").value;
      if (pose) post("/api/pose", { pose }, "pose-result", $("pose-go"));
    });
    window.addEventListener("hashchange", () => {
      readHash();
      writeHash();
      $("window-select").value = String(view.window);
      showTab(view.tab);
    });
  }

  document.addEventListener("DOMContentLoaded", () => {
    readHash();
    writeHash();   // a bad or partial hash is rewritten to the view really shown
    buildTable();
    wire();
    showTab(view.tab);
    loadPoses();
    loadHistory().finally(connect);
    setInterval(flushCharts, CHART_MS);
  });
})();
