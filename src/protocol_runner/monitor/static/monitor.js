// protocol-runner live monitor: reads the /events stream and draws on <canvas>. No library, no network
// beyond this server. Read-only: nothing here sends anything but GET requests for the stream.
"use strict";
(function () {
  const $ = (id) => document.getElementById(id);
  const body = document.body;
  const query = window.location.search; // carries ?token=... when the monitor needs one
  const MAX_LOOP = 20000;
  const KEPT = { verdicts: 12, events: 30 };
  const S = {
    joints: new Map(), selected: null, wanted: null, windowS: 15, messages: 0, points: 0, frames: 0, ended: null, dirty: false,
    progress: null, progressAt: 0, source: null,
  };

  // ------------------------------------------------------------------------------------- helpers
  function fmtS(s) {
    if (s === null || s === undefined || !isFinite(s)) return "?";
    s = Math.max(0, s);
    if (s >= 3600) return (s / 3600).toFixed(1) + " h";
    if (s >= 90) return Math.round(s / 60) + " min";
    return s.toFixed(0) + " s";
  }
  function el(tag, cls, text) {
    const e = document.createElement(tag);
    if (cls) e.className = cls;
    if (text !== undefined) e.textContent = text;
    return e;
  }
  function setData(name, value) { body.setAttribute("data-" + name, String(value)); }
  function banner(kind, text) {
    const b = $("banner");
    b.className = kind ? "banner " + kind : "banner hidden";
    b.textContent = text || "";
  }
  function niceTicks(lo, hi, n) {
    const span = hi - lo;
    if (!(span > 0)) return [lo];
    const raw = span / n, mag = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 5, 10].map((m) => m * mag).find((s) => span / s <= n) || 10 * mag;
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + 1e-9; v += step) out.push(Math.abs(v) < 1e-12 ? 0 : v);
    return out;
  }
  function range(arrays, minSpan) {
    let lo = Infinity, hi = -Infinity;
    for (const a of arrays) for (const v of a) { if (v === null) continue; if (v < lo) lo = v; if (v > hi) hi = v; }
    if (!isFinite(lo)) return [0, 1];
    const mid = (lo + hi) / 2, half = Math.max((hi - lo) / 2, minSpan / 2) * 1.08;
    return [mid - half, mid + half];
  }

  // ---------------------------------------------------------------------------------- the joints
  // Every driven joint has a small angle/torque panel (shown when there are several: small multiples);
  // one joint, the selected one, is enlarged below them with its torque-angle loop. Clicking a small
  // panel, or the selector, chooses the joint to enlarge.
  function joint(name) {
    let j = S.joints.get(name);
    if (j) return j;
    const mini = el("button", "mini");
    mini.type = "button";
    mini.setAttribute("data-joint", name);
    mini.setAttribute("aria-pressed", "false");
    mini.title = "enlarge " + name;
    const head = el("div", "mini-head");
    const now = el("span", "mini-now");
    head.append(el("span", "mini-name", name), now);
    const canvas = el("canvas", "mini-traces");
    canvas.setAttribute("data-joint", name);
    mini.append(head, canvas);
    mini.addEventListener("click", () => choose(name));
    $("minis").appendChild(mini);
    const option = el("option", null, name);
    option.value = name;
    $("joint-select").appendChild(option);
    j = { name, t: [], cmd: [], angle: [], torque: [], loop: [], loopWhere: null, where: "", mini, miniCanvas: canvas, now };
    S.joints.set(name, j);
    const many = S.joints.size > 1;
    $("minis").hidden = !many;
    $("joint-pick").hidden = !many;
    setData("joints", S.joints.size);
    if (S.selected === null || name === S.wanted) select(name);
    return j;
  }

  function select(name) {
    const j = S.joints.get(name);
    if (!j) return;
    S.selected = name;
    for (const other of S.joints.values()) other.mini.setAttribute("aria-pressed", String(other === j));
    $("focus").hidden = false;
    $("focus-name").textContent = "joint " + name;
    $("joint-select").value = name;
    $("focus-traces").setAttribute("data-joint", name);
    $("focus-loop").setAttribute("data-joint", name);
    $("focus-where").textContent = j.where;
    setData("selected", name);
    S.dirty = true;
  }

  function choose(name) {
    S.wanted = name; // kept when the page reconnects and the joints are shown anew
    select(name);
  }

  function clearJoints() {
    S.joints.clear();
    S.selected = null;
    $("minis").replaceChildren();
    $("joint-select").replaceChildren();
    $("minis").hidden = true;
    $("joint-pick").hidden = true;
    $("focus").hidden = true;
    setData("joints", 0);
  }

  function addSamples(m) {
    const j = joint(m.joint);
    const pts = m.points || [];
    for (const p of pts) { j.t.push(p[0]); j.cmd.push(p[1]); j.angle.push(p[2]); j.torque.push(p[3]); }
    if (m.phase === "run") {
      if (j.loopWhere !== m.where) { j.loop = []; j.loopWhere = m.where; }
      for (const p of pts) j.loop.push([p[2], p[3]]);
      if (j.loop.length > MAX_LOOP) j.loop.splice(0, j.loop.length - MAX_LOOP);
    }
    const last = j.t.length ? j.t[j.t.length - 1] : null;
    if (last !== null) {
      let cut = 0;
      while (cut < j.t.length && j.t[cut] < last - S.windowS - 1) cut++;
      if (cut > 0) for (const a of [j.t, j.cmd, j.angle, j.torque]) a.splice(0, cut);
      setData("last-t", last.toFixed(3));
    }
    j.where = m.where ? "· " + m.where + " (" + m.phase + ")" : "";
    if (j.name === S.selected) $("focus-where").textContent = j.where;
    if (pts.length) {
      const p = pts[pts.length - 1];
      j.now.textContent = (p[2] === null ? "?" : p[2].toFixed(1)) + " deg · " + (p[3] === null ? "?" : p[3].toFixed(1)) + " N·m";
    }
    S.points += pts.length;
    setData("points", S.points);
    S.dirty = true;
  }

  // ------------------------------------------------------------------------------------ drawing
  function prepare(canvas, small) {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(small ? 120 : 200, canvas.clientWidth), h = Math.max(small ? 90 : 150, canvas.clientHeight);
    if (canvas.width !== Math.round(w * dpr) || canvas.height !== Math.round(h * dpr)) {
      canvas.width = Math.round(w * dpr);
      canvas.height = Math.round(h * dpr);
    }
    const ctx = canvas.getContext("2d");
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, w, h);
    ctx.font = "11px system-ui, sans-serif";
    return { ctx, w, h };
  }

  function axes(ctx, box, xr, yr, xlabel, ylabel, xfmt, yticks) {
    const { x0, y0, w, h } = box;
    ctx.strokeStyle = "#e3e7ee"; ctx.fillStyle = "#667085"; ctx.lineWidth = 1;
    ctx.textAlign = "right"; ctx.textBaseline = "middle";
    for (const v of niceTicks(yr[0], yr[1], yticks || 4)) {
      const y = y0 + h - ((v - yr[0]) / (yr[1] - yr[0])) * h;
      ctx.beginPath(); ctx.moveTo(x0, y); ctx.lineTo(x0 + w, y); ctx.stroke();
      ctx.fillText(String(+v.toFixed(2)), x0 - 4, y);
    }
    ctx.textAlign = "center"; ctx.textBaseline = "top";
    for (const v of niceTicks(xr[0], xr[1], yticks ? 2 * yticks - 1 : 6)) {
      const x = x0 + ((v - xr[0]) / (xr[1] - xr[0])) * w;
      ctx.beginPath(); ctx.moveTo(x, y0); ctx.lineTo(x, y0 + h); ctx.stroke();
      ctx.fillText(xfmt ? xfmt(v) : String(+v.toFixed(2)), x, y0 + h + 3);
    }
    ctx.strokeStyle = "#b8c0cc"; ctx.strokeRect(x0, y0, w, h);
    if (yticks) { // a small panel: its unit inside the panel's top left corner
      ctx.textAlign = "left"; ctx.textBaseline = "top"; ctx.fillText(ylabel, x0 + 3, y0 + 2);
    } else {
      ctx.save(); ctx.translate(x0 - 34, y0 + h / 2); ctx.rotate(-Math.PI / 2);
      ctx.textAlign = "center"; ctx.textBaseline = "bottom"; ctx.fillText(ylabel, 0, 0); ctx.restore();
    }
    if (xlabel) { ctx.textAlign = "right"; ctx.textBaseline = "bottom"; ctx.fillText(xlabel, x0 + w, y0 - 2); }
  }

  function line(ctx, box, xr, yr, xs, ys, color, dash) {
    const { x0, y0, w, h } = box;
    ctx.strokeStyle = color; ctx.lineWidth = 1.6; ctx.setLineDash(dash || []);
    ctx.beginPath();
    let pen = false;
    for (let i = 0; i < xs.length; i++) {
      if (ys[i] === null || xs[i] < xr[0]) { pen = false; continue; }
      const x = x0 + ((xs[i] - xr[0]) / (xr[1] - xr[0])) * w;
      const y = y0 + h - ((ys[i] - yr[0]) / (yr[1] - yr[0])) * h;
      if (pen) ctx.lineTo(x, y); else ctx.moveTo(x, y);
      pen = true;
    }
    ctx.stroke(); ctx.setLineDash([]);
  }

  function drawTraces(canvas, j, small) {
    const { ctx, w, h } = prepare(canvas, small);
    const last = j.t.length ? j.t[j.t.length - 1] : 0;
    const xr = [last - S.windowS, last];
    const left = small ? 30 : 48, gap = small ? 18 : 26, panel = (h - 20 - gap - (small ? 12 : 18)) / 2;
    const top = { x0: left, y0: small ? 6 : 14, w: w - left - (small ? 6 : 10), h: panel };
    const bottom = { x0: left, y0: top.y0 + panel + gap, w: top.w, h: panel };
    const rel = (v) => (v - last).toFixed(0) + " s";
    const visible = (a) => a.filter((_, i) => j.t[i] >= xr[0]);
    const ar = range([visible(j.cmd), visible(j.angle)], 5);
    const tr = range([visible(j.torque)], 2);
    const ticks = small ? 2 : undefined; // a small panel: fewer ticks, its unit inside
    axes(ctx, top, xr, ar, "", small ? "deg" : "angle (deg)", rel, ticks);
    axes(ctx, bottom, xr, tr, "", small ? "N·m" : "torque (N·m)", rel, ticks);
    line(ctx, top, xr, ar, j.t, j.cmd, "#8a94a6", [5, 4]);
    line(ctx, top, xr, ar, j.t, j.angle, "#1f6fd1");
    line(ctx, bottom, xr, tr, j.t, j.torque, "#d9480f");
  }

  function drawLoop(canvas, j) {
    const { ctx, w, h } = prepare(canvas);
    const box = { x0: 48, y0: 14, w: w - 58, h: h - 38 };
    const xs = j.loop.map((p) => p[0]), ys = j.loop.map((p) => p[1]);
    const xr = range([xs], 5), yr = range([ys], 2);
    axes(ctx, box, xr, yr, "angle (deg) →", "torque (N·m)");
    line(ctx, box, xr, yr, xs, ys, "#7048e8");
    if (xs.length) {
      const x = box.x0 + ((xs[xs.length - 1] - xr[0]) / (xr[1] - xr[0])) * box.w;
      const y = box.y0 + box.h - ((ys[ys.length - 1] - yr[0]) / (yr[1] - yr[0])) * box.h;
      ctx.fillStyle = "#d9480f"; ctx.beginPath(); ctx.arc(x, y, 4, 0, 2 * Math.PI); ctx.fill();
    } else {
      ctx.fillStyle = "#98a2b3"; ctx.textAlign = "center"; ctx.fillText("the loop builds up during a run", box.x0 + box.w / 2, box.y0 + box.h / 2);
    }
  }

  function frame() {
    if (S.dirty) {
      S.dirty = false;
      if (S.joints.size > 1) for (const j of S.joints.values()) drawTraces(j.miniCanvas, j, true);
      const j = S.joints.get(S.selected);
      if (j) { drawTraces($("focus-traces"), j, false); drawLoop($("focus-loop"), j); }
      S.frames += 1;
      setData("frames", S.frames);
    }
    window.requestAnimationFrame(frame);
  }

  // ----------------------------------------------------------------------------------- messages
  function showSession(m) {
    if (!m) return;
    const parts = [m.protocol, m.mode, m.folder];
    if (m.resumed) parts.push("resumed");
    if (m.only && m.only.length) parts.push("only " + m.only.join(","));
    $("session").textContent = parts.join(" · ");
    for (const name of m.joints || []) joint(name);
  }

  function showStep(m) {
    if (!m) return;
    $("now").textContent = m.describe || m.step;
    const extra = m.robot_time_s ? " · about " + fmtS(m.robot_time_s) + " of motion" : "";
    const index = m.index ? "step " + m.index + " of " + m.total + " · " : "";
    $("now-id").textContent = index + m.step + extra;
    setData("step", m.step);
    const next = m.next_action, list = $("next-items");
    list.replaceChildren();
    if (!next) { $("next").textContent = "none left in the plan"; return; }
    const when = next.steps_away <= 1 ? "next step" : "in " + next.steps_away + " steps, after about " + fmtS(next.robot_s_until) + " of motion";
    $("next").textContent = next.title + " (" + when + ")";
    for (const item of next.items || []) list.appendChild(el("li", null, item));
  }

  function showProgress(m) {
    if (!m) return;
    S.progress = m; S.progressAt = Date.now();
    const frac = m.robot_s_total > 0 ? m.robot_s_done / m.robot_s_total : (m.total ? m.done / m.total : 0);
    $("progress-fill").style.width = (100 * Math.min(1, frac)).toFixed(1) + "%";
    $("progress-text").textContent = m.done + " of " + m.total + " steps · robot time left " + fmtS(m.robot_s_remaining);
    tickEta();
  }

  function tickEta() {
    const m = S.progress;
    if (!m) return;
    if (S.ended) { $("eta").textContent = "elapsed " + fmtS(m.elapsed_s); return; }
    const eta = m.eta_s === null ? null : m.eta_s - (Date.now() - S.progressAt) / 1000;
    $("eta").textContent = "ETA " + (eta === null ? "after the first motion" : fmtS(eta) + " (wall clock)");
  }

  function addVerdict(m) {
    const tbody = $("verdicts").tBodies[0];
    const row = el("tr");
    row.append(el("td", null, m.step), el("td", m.verdict, m.verdict),
      el("td", null, m.settle_error_deg !== undefined ? m.settle_error_deg.toFixed(2) + " deg" : ""),
      el("td", null, m.time_constant_s !== undefined ? m.time_constant_s.toFixed(3) + " s" : ""));
    if (m.message) row.title = m.message;
    tbody.insertBefore(row, tbody.firstChild);
    while (tbody.rows.length > KEPT.verdicts) tbody.deleteRow(-1);
  }

  function addEvent(kind, detail, bad) {
    const list = $("events");
    const li = el("li", bad ? "bad" : "");
    li.append(el("span", "kind", kind), document.createTextNode(detail || ""));
    list.insertBefore(li, list.firstChild);
    while (list.children.length > KEPT.events) list.removeChild(list.lastChild);
  }

  function showOperator(m) {
    if (S.ended) return;
    if (!m || !m.waiting) { banner(null); return; }
    const items = (m.items || []).map((i) => "• " + i).join("\n");
    banner("wait", "Waiting for the operator at the terminal: " + m.prompt + (items ? "\n" + items : ""));
  }

  function showEnd(m) {
    if (!m) return;
    S.ended = m;
    const ok = m.status === "complete";
    banner(ok ? "ok" : "bad", (ok ? "Session complete: " : "Session " + m.status + ": ") + m.message);
    setData("state", "ended");
    $("conn").textContent = "session over";
    $("conn").className = "conn";
    tickEta();
    if (S.source) S.source.close();
  }

  const BAD_EVENTS = new Set(["aborted", "interrupted", "stopped", "operator_override", "redo"]);

  function handle(m) {
    S.messages += 1;
    setData("messages", S.messages);
    switch (m.type) {
      case "hello": {
        const s = m.snapshot || {};
        clearJoints();
        $("verdicts").tBodies[0].replaceChildren();
        $("events").replaceChildren();
        S.windowS = s.trace_window_s || S.windowS;
        $("focus-window").textContent = String(S.windowS);
        showSession(s.session); showStep(s.step); showProgress(s.progress);
        for (const v of s.verdicts || []) addVerdict(v);
        for (const e of s.events || []) addEvent(e.kind, e.detail, BAD_EVENTS.has(e.kind));
        showOperator(s.operator);
        if (s.ended) showEnd(s.ended);
        break;
      }
      case "session": showSession(m); break;
      case "step_start": showStep(m); break;
      case "step_end": $("last-done").textContent = "finished " + m.step + ": " + m.summary; break;
      case "samples": addSamples(m); break;
      case "progress": showProgress(m); break;
      case "verdict": addVerdict(m); break;
      case "event": addEvent(m.kind, m.detail, BAD_EVENTS.has(m.kind)); break;
      case "operator_wait": showOperator(m); break;
      case "session_end": showEnd(m); break;
      default: break;
    }
  }

  function connect() {
    const source = new EventSource("events" + query);
    S.source = source;
    source.onopen = () => {
      setData("state", "live");
      $("conn").textContent = "live";
      $("conn").className = "conn live";
      if (!S.ended && $("banner").classList.contains("lost")) banner(null);
    };
    source.onmessage = (ev) => {
      let m;
      try { m = JSON.parse(ev.data); } catch (e) { return; }
      handle(m);
    };
    source.onerror = () => {
      if (S.ended) return;
      setData("state", "lost");
      $("conn").textContent = "connection lost, retrying…";
      $("conn").className = "conn lost";
      banner("lost", "No contact with the session's monitor. The session may have ended or been stopped; retrying.");
    };
  }

  $("joint-select").addEventListener("change", (ev) => choose(ev.target.value));
  setInterval(tickEta, 1000);
  window.requestAnimationFrame(frame);
  connect();
})();
