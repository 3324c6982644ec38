// mbsolve viewer: draws the drawing model of src/drawing.rs on a canvas.
// `marks` is a port of Drawing::marks (same parts, same geometry, same
// order); the inks' colours and widths are those of `mbsolve animate`.
// Errors are written into #errors (and counted in its data-count), so a
// headless browser's DOM dump shows them.
"use strict";
(function () {
  const errorsEl = document.getElementById("errors");
  let errorCount = 0;
  function reportError(msg) {
    errorCount += 1;
    errorsEl.dataset.count = String(errorCount);
    errorsEl.textContent += "error: " + msg + "\n";
  }
  window.addEventListener("error", (e) => reportError(e.message + " (" + (e.lineno || "?") + ")"));
  window.addEventListener("unhandledrejection", (e) => reportError(String(e.reason)));
  const consoleError = console.error.bind(console);
  console.error = function (...args) { reportError(args.map(String).join(" ")); consoleError(...args); };
  errorsEl.dataset.count = "0";

  try { main(); } catch (e) { reportError(e && e.stack ? e.stack : String(e)); }

  function main() {
    const data = JSON.parse(document.getElementById("data").textContent);
    const D = data.drawing;
    const T = data.t, Q = data.q, N = T.length;
    const INK = {
      body: "#0072B2", ground: "#444444", hatch: "#888888",
      spring: "#D55E00", damper: "#009E73", contact: "#CC79A7",
      reaction: "#E69F00",
    };
    const WIDTH = { hatch: 1 };
    const BODY_FILL = "rgba(86,180,233,0.5)", GROUND_FILL = "#bbbbbb";

    // ---- geometry (src/drawing.rs) ----
    const add = (a, b) => [a[0] + b[0], a[1] + b[1]];
    const sub = (a, b) => [a[0] - b[0], a[1] - b[1]];
    const mul = (a, k) => [a[0] * k, a[1] * k];
    const norm = (a) => Math.hypot(a[0], a[1]);
    const perp = (a) => [-a[1], a[0]];
    function world(q, body, s) {
      if (body === null || body === undefined) return s;
      const i = 3 * body, c = Math.cos(q[i + 2]), sn = Math.sin(q[i + 2]);
      return [q[i] + c * s[0] - sn * s[1], q[i + 1] + sn * s[0] + c * s[1]];
    }
    function zigzag(a, b, width, offset) {
      const d = sub(b, a), len = Math.max(norm(d), 1e-300);
      const e = mul(d, 1 / len), n = perp(e);
      const at = (u, side) => add(add(a, mul(e, u * len)), mul(n, offset + side));
      const p = [a, at(0.1, -offset), at(0.1, 0), at(0.25, 0)];
      const turns = 12;
      for (let k = 1; k < turns; k++) {
        const u = 0.25 + 0.5 * k / turns;
        p.push(at(u, (k % 2 === 1 ? 0.5 : -0.5) * width));
      }
      p.push(at(0.75, 0), at(0.9, 0), at(0.9, -offset), b);
      return p;
    }
    function dashpot(a, b, width, offset, rest) {
      const d = sub(b, a), len = Math.max(norm(d), 1e-300);
      const e = mul(d, 1 / len), n = perp(e);
      const at = (u, side) => add(add(a, mul(e, u)), mul(n, offset + side));
      const base = 0.15 * Math.min(len, rest), lead = 0.5 * base, cyl = 0.5 * rest, h = 0.5 * width;
      const s = Math.min(Math.max(base + 0.5 * cyl + (len - rest), base + 0.05 * cyl), base + cyl);
      const end = Math.max(len - lead, s);
      return [
        [a, at(lead, -offset), at(lead, 0), at(base, 0), at(base, -h), at(base + cyl, -h)],
        [at(base, 0), at(base, h), at(base + cyl, h)],
        [at(s, 0.8 * h), at(s, -0.8 * h)],
        [at(s, 0), at(end, 0), at(end, -offset), b],
      ];
    }
    function hatched(out, a, b, normal, h) {
      out.push({ kind: "line", points: [a, b], ink: "ground" });
      const d = sub(b, a), l = norm(d);
      if (!(h > 0) || l <= 0) return;
      const e = mul(d, 1 / l);
      const k = Math.min(Math.floor(l / h), 2000);
      for (let i = 0; i <= k; i++) {
        const p = add(a, mul(e, i * h));
        out.push({ kind: "line", points: [p, add(p, add(mul(normal, -h), mul(e, -0.6 * h)))], ink: "hatch" });
      }
    }
    function marks(q) {
      const out = [];
      for (const p of D.parts) {
        switch (p.kind) {
          case "polygon":
            out.push({ kind: "fill", points: p.points.map((s) => world(q, p.body, s)), ink: "body" });
            break;
          case "bar": {
            const a = world(q, p.body, p.a), b = world(q, p.body, p.b);
            const d = sub(b, a), l = norm(d);
            let e = l > 0 ? mul(d, 1 / l) : [1, 0];
            const n = mul(perp(e), 0.5 * p.width);
            e = mul(e, 0.5 * p.width);
            out.push({ kind: "fill", points: [sub(sub(a, e), n), sub(add(b, e), n), add(add(b, e), n), add(sub(a, e), n)], ink: "body" });
            break;
          }
          case "disc": {
            const c = world(q, p.body, p.centre);
            out.push({ kind: "circle", centre: c, radius: p.radius, ink: "body", filled: true });
            out.push({ kind: "line", points: [c, world(q, p.body, add(p.centre, [p.radius, 0]))], ink: "body" });
            break;
          }
          case "contact": {
            const c = world(q, p.body, p.centre);
            if (p.radius > 0) {
              out.push({ kind: "circle", centre: c, radius: p.radius, ink: "contact", filled: false });
            } else {
              const h = 0.015 * D.scale;
              out.push({ kind: "line", points: [sub(c, [h, h]), add(c, [h, h])], ink: "contact" });
              out.push({ kind: "line", points: [add(c, [-h, h]), add(c, [h, -h])], ink: "contact" });
            }
            break;
          }
          case "pin":
            out.push({ kind: "pin", centre: world(q, p.body, p.at) });
            break;
          case "support": {
            const h = p.size, w = 0.6 * p.size;
            const down = p.down || [0, -1];
            const base = add(p.at, mul(down, h)), side = perp(down);
            out.push({ kind: "fill", points: [p.at, add(base, mul(side, -w)), add(base, mul(side, w))], ink: "ground" });
            hatched(out, add(base, mul(side, -1.6 * w)), add(base, mul(side, 1.6 * w)), mul(down, -1), 0.4 * h);
            break;
          }
          case "ground":
            hatched(out, p.a, p.b, p.normal, p.hatch);
            break;
          case "guide": {
            const n = perp(p.axis);
            for (const side of [-0.5, 0.5]) {
              const p0 = add(add(p.point, mul(p.axis, p.from)), mul(n, side * p.gap));
              const p1 = add(add(p.point, mul(p.axis, p.to)), mul(n, side * p.gap));
              const w0 = world(q, p.body, p0), w1 = world(q, p.body, p1);
              if (p.body === null || p.body === undefined) {
                hatched(out, w0, w1, mul(n, side < 0 ? 1 : -1), 0.02 * D.scale);
              } else {
                out.push({ kind: "line", points: [w0, w1], ink: "ground" });
              }
            }
            break;
          }
          case "spring":
            out.push({ kind: "line", points: zigzag(world(q, p.body_i, p.a), world(q, p.body_j, p.b), p.width, p.offset), ink: "spring" });
            break;
          case "damper": {
            for (const pts of dashpot(world(q, p.body_i, p.a), world(q, p.body_j, p.b), p.width, p.offset, p.rest)) {
              out.push({ kind: "line", points: pts, ink: "damper" });
            }
            break;
          }
          default:
            throw new Error("unknown part kind " + p.kind);
        }
      }
      return out;
    }
    function scaleBar(max) {
      if (!(isFinite(max) && max > 0)) return 1;
      const e = Math.pow(10, Math.floor(Math.log10(max)));
      for (const m of [5, 2, 1]) if (m * e <= max) return m * e;
      return e;
    }
    function barLabel(l) {
      if (l >= 1) return l + " m";
      if (l >= 1e-3) return Math.round(l * 1e3 * 1e6) / 1e6 + " mm";
      return l.toExponential() + " m";
    }

    // ---- page ----
    const canvas = document.getElementById("scene");
    canvas.width = data.canvas[0];
    canvas.height = data.canvas[1];
    const ctx = canvas.getContext("2d");
    document.getElementById("title").textContent = data.title;
    document.getElementById("description").textContent = data.description;
    document.title = data.title + " — mbsolve viewer";
    const info = document.getElementById("info");
    info.textContent = N + " output rows, t = " + T[0] + " … " + T[N - 1] + " s" +
      (data.stride > 1 ? " (every " + data.stride + "th row of the run's table)" : "") +
      ". Drag to pan, wheel to zoom; space plays and pauses, ← → step.";
    const slider = document.getElementById("slider");
    slider.max = String(N - 1);
    const timeEl = document.getElementById("time");
    const playBtn = document.getElementById("play");
    const speedSel = document.getElementById("speed");

    // view: the fit of animate (88 % of the tighter side), then zoom and pan
    const B = D.bounds;
    function fit() {
      const w = canvas.width, h = canvas.height;
      const sx = Math.max(B[2] - B[0], 1e-9), sy = Math.max(B[3] - B[1], 1e-9);
      const k = 0.88 * Math.min(w / sx, h / sy);
      return { k: k, ox: 0.5 * w - k * 0.5 * (B[0] + B[2]), oy: 0.5 * h + k * 0.5 * (B[1] + B[3]) };
    }
    let V = fit();

    // ---- force arrows (src/drawing/arrows.rs): per row [x, y, fx, fy] ----
    const A = data.arrows || null;
    const forcesBox = document.getElementById("forces");
    if (A) {
      document.getElementById("forces-label").hidden = false;
      forcesBox.addEventListener("change", () => draw());
    }
    function arrowPath(from, d, head) {
      const l = norm(d);
      if (!(l > 0 && isFinite(l))) return [];
      const e = mul(d, 1 / l), tip = add(from, d), h = Math.min(head, 0.4 * l);
      const back = sub(tip, mul(e, h)), side = mul(perp(e), 0.5 * h);
      return [[from, tip], [add(back, side), tip, sub(back, side)]];
    }
    function drawArrows(px) {
      const stroke = (pts, colour) => {
        ctx.beginPath();
        pts.forEach((p, i) => { const [x, y] = px(p); if (i === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y); });
        ctx.strokeStyle = colour; ctx.lineWidth = 2; ctx.stroke();
      };
      A.rows[row].forEach((a, j) => {
        const d = [a[2] * A.metres_per_newton, a[3] * A.metres_per_newton];
        for (const pts of arrowPath([a[0], a[1]], d, A.head)) stroke(pts, INK[A.kinds[j]]);
      });
      // the key, bottom right: the key force's arrow and its value
      const len = A.key_force * A.metres_per_newton * V.k;
      const y = canvas.height - 12, x1 = canvas.width - 12;
      const h = Math.min(A.head * V.k, 0.4 * len);
      const idPx = (p) => p;
      for (const pts of arrowPath([x1 - len, y], [len, 0], h)) {
        ctx.beginPath();
        pts.forEach((p, i) => { const [x, yy] = idPx(p); if (i === 0) ctx.moveTo(x, yy); else ctx.lineTo(x, yy); });
        ctx.strokeStyle = "black"; ctx.lineWidth = 2; ctx.stroke();
      }
      ctx.fillStyle = "black";
      ctx.textAlign = "right";
      ctx.fillText(A.label, x1 - len - 6, y - 7);
      ctx.textAlign = "left";
    }
    let row = 0, playing = false, simTime = T[0], lastFrame = null;

    function draw() {
      const q = Q[row];
      const px = (p) => [V.ox + V.k * p[0], V.oy - V.k * p[1]];
      ctx.fillStyle = "white";
      ctx.fillRect(0, 0, canvas.width, canvas.height);
      ctx.lineJoin = "round";
      for (const m of marks(q)) {
        if (m.kind === "fill" || m.kind === "line") {
          ctx.beginPath();
          m.points.forEach((p, i) => { const [x, y] = px(p); if (i === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y); });
          if (m.kind === "fill") {
            ctx.closePath();
            ctx.fillStyle = m.ink === "body" ? BODY_FILL : GROUND_FILL;
            ctx.fill();
          }
          ctx.strokeStyle = INK[m.ink];
          ctx.lineWidth = WIDTH[m.ink] || 2;
          ctx.stroke();
        } else if (m.kind === "circle") {
          const [x, y] = px(m.centre);
          ctx.beginPath();
          ctx.arc(x, y, Math.max(1, V.k * m.radius), 0, 2 * Math.PI);
          if (m.filled) { ctx.fillStyle = BODY_FILL; ctx.fill(); }
          ctx.strokeStyle = INK[m.ink];
          ctx.lineWidth = 2;
          ctx.stroke();
        } else if (m.kind === "pin") {
          const [x, y] = px(m.centre);
          ctx.beginPath();
          ctx.arc(x, y, 4, 0, 2 * Math.PI);
          ctx.fillStyle = "white";
          ctx.fill();
          ctx.strokeStyle = "black";
          ctx.lineWidth = 1;
          ctx.stroke();
        }
      }
      const label = "t = " + T[row].toFixed(3) + " s";
      ctx.fillStyle = "black";
      ctx.font = "14px sans-serif";
      ctx.textBaseline = "top";
      ctx.fillText(label, 8, 8);
      const bar = scaleBar(0.2 * canvas.width / V.k);
      const x0 = 10, y0 = canvas.height - 12, x1 = x0 + Math.round(bar * V.k);
      ctx.beginPath();
      ctx.moveTo(x0, y0 - 4); ctx.lineTo(x0, y0); ctx.lineTo(x1, y0); ctx.lineTo(x1, y0 - 4);
      ctx.strokeStyle = "black"; ctx.lineWidth = 2; ctx.stroke();
      ctx.fillText(barLabel(bar), x1 + 6, y0 - 12);
      if (A && forcesBox.checked) drawArrows(px);
      timeEl.textContent = label;
      slider.value = String(row);
      drawPlots();
    }

    // ---- plots ----
    const plotsEl = document.getElementById("plots");
    const colsEl = document.getElementById("columns");
    const shown = new Set(data.plot);
    const plots = [];
    data.columns.forEach((c) => {
      const lab = document.createElement("label");
      const box = document.createElement("input");
      box.type = "checkbox";
      box.checked = shown.has(c.name);
      box.addEventListener("change", () => { if (box.checked) shown.add(c.name); else shown.delete(c.name); buildPlots(); });
      lab.appendChild(box);
      lab.appendChild(document.createTextNode(" " + c.name + (c.unit ? " [" + c.unit + "]" : "")));
      colsEl.appendChild(lab);
    });
    function buildPlots() {
      plotsEl.textContent = "";
      plots.length = 0;
      for (const c of data.columns) {
        if (!shown.has(c.name)) continue;
        const cv = document.createElement("canvas");
        cv.className = "plot";
        cv.width = 520; cv.height = 180;
        cv.setAttribute("aria-label", c.name);
        plotsEl.appendChild(cv);
        let lo = Infinity, hi = -Infinity;
        for (const v of c.values) if (v !== null) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
        if (!(lo <= hi)) { lo = 0; hi = 1; }
        if (hi - lo < 1e-12 * Math.max(1, Math.abs(hi))) { lo -= 0.5; hi += 0.5; }
        const pad = 0.05 * (hi - lo);
        const P = { c: c, cv: cv, lo: lo - pad, hi: hi + pad, L: 62, R: 10, Tp: 20, Bm: 24 };
        cv.addEventListener("click", (e) => {
          const r = cv.getBoundingClientRect();
          const t = T[0] + (e.clientX - r.left - P.L) / (cv.width - P.L - P.R) * (T[N - 1] - T[0]);
          seekTime(t);
          pause();
        });
        plots.push(P);
      }
      drawPlots();
    }
    function fmt(v) {
      const a = Math.abs(v);
      return a !== 0 && (a < 1e-3 || a >= 1e4) ? v.toExponential(2) : String(+v.toPrecision(4));
    }
    function drawPlots() {
      for (const P of plots) {
        const g = P.cv.getContext("2d"), w = P.cv.width, h = P.cv.height;
        const X = (t) => P.L + (T[N - 1] > T[0] ? (t - T[0]) / (T[N - 1] - T[0]) : 0) * (w - P.L - P.R);
        const Y = (v) => P.Tp + (P.hi - v) / (P.hi - P.lo) * (h - P.Tp - P.Bm);
        g.fillStyle = "white"; g.fillRect(0, 0, w, h);
        g.strokeStyle = "#999"; g.lineWidth = 1;
        g.strokeRect(P.L, P.Tp, w - P.L - P.R, h - P.Tp - P.Bm);
        g.fillStyle = "#222"; g.font = "12px sans-serif"; g.textBaseline = "middle";
        g.textAlign = "right";
        g.fillText(fmt(P.hi), P.L - 4, P.Tp + 6); g.fillText(fmt(P.lo), P.L - 4, h - P.Bm - 6);
        g.textAlign = "left";
        g.fillText(P.c.name + (P.c.unit ? " [" + P.c.unit + "]" : ""), P.L, 9);
        g.textAlign = "center";
        g.fillText(String(T[0]), P.L, h - 10); g.fillText(T[N - 1] + " s", w - P.R - 12, h - 10);
        g.beginPath();
        let pen = false;
        P.c.values.forEach((v, i) => {
          if (v === null) { pen = false; return; }
          if (pen) g.lineTo(X(T[i]), Y(v)); else g.moveTo(X(T[i]), Y(v));
          pen = true;
        });
        g.strokeStyle = "#0072B2"; g.lineWidth = 1.5; g.stroke();
        const x = X(T[row]);
        g.beginPath(); g.moveTo(x, P.Tp); g.lineTo(x, h - P.Bm);
        g.strokeStyle = "#D55E00"; g.lineWidth = 1.5; g.stroke();
        const v = P.c.values[row];
        g.textAlign = "right"; g.fillStyle = "#D55E00";
        g.fillText(v === null ? "–" : fmt(v), w - P.R - 2, 9);
      }
    }

    // ---- time ----
    function rowAt(t) {
      // the output row nearest to t (binary search on increasing T)
      let lo = 0, hi = N - 1;
      while (hi - lo > 1) { const m = (lo + hi) >> 1; if (T[m] <= t) lo = m; else hi = m; }
      return Math.abs(T[hi] - t) < Math.abs(T[lo] - t) ? hi : lo;
    }
    function seekTime(t) { simTime = Math.min(Math.max(t, T[0]), T[N - 1]); row = rowAt(simTime); draw(); }
    function seekRow(r) { row = Math.min(Math.max(r, 0), N - 1); simTime = T[row]; draw(); }
    function pause() { playing = false; playBtn.textContent = "Play"; }
    function play() {
      if (row >= N - 1) seekRow(0);
      playing = true; lastFrame = null; playBtn.textContent = "Pause";
      requestAnimationFrame(tick);
    }
    function tick(now) {
      if (!playing) return;
      if (lastFrame !== null) {
        // honest time: simulated time advances by wall time × speed
        simTime += (now - lastFrame) / 1000 * Number(speedSel.value);
        if (simTime >= T[N - 1]) { simTime = T[N - 1]; row = N - 1; draw(); pause(); return; }
        row = rowAt(simTime);
        draw();
      }
      lastFrame = now;
      requestAnimationFrame(tick);
    }
    playBtn.addEventListener("click", () => (playing ? pause() : play()));
    slider.addEventListener("input", () => { pause(); seekRow(Number(slider.value)); });
    document.addEventListener("keydown", (e) => {
      if (e.target && e.target.tagName === "INPUT" && e.target.type === "checkbox") return;
      if (e.key === " ") { e.preventDefault(); playing ? pause() : play(); }
      else if (e.key === "ArrowRight") { pause(); seekRow(row + 1); }
      else if (e.key === "ArrowLeft") { pause(); seekRow(row - 1); }
    });

    // ---- zoom and pan ----
    function zoomAt(f, x, y) {
      V = { k: V.k * f, ox: x - (x - V.ox) * f, oy: y - (y - V.oy) * f };
      draw();
    }
    canvas.addEventListener("wheel", (e) => {
      e.preventDefault();
      const r = canvas.getBoundingClientRect();
      zoomAt(e.deltaY < 0 ? 1.2 : 1 / 1.2, e.clientX - r.left, e.clientY - r.top);
    }, { passive: false });
    let drag = null;
    canvas.addEventListener("pointerdown", (e) => { drag = [e.clientX, e.clientY]; canvas.setPointerCapture(e.pointerId); });
    canvas.addEventListener("pointermove", (e) => {
      if (!drag) return;
      V.ox += e.clientX - drag[0]; V.oy += e.clientY - drag[1];
      drag = [e.clientX, e.clientY];
      draw();
    });
    canvas.addEventListener("pointerup", () => { drag = null; });
    document.getElementById("zoomin").addEventListener("click", () => zoomAt(1.25, canvas.width / 2, canvas.height / 2));
    document.getElementById("zoomout").addEventListener("click", () => zoomAt(0.8, canvas.width / 2, canvas.height / 2));
    document.getElementById("reset").addEventListener("click", () => { V = fit(); draw(); });

    // ---- start: #t=SECONDS opens paused at that time ----
    function fromHash() {
      const m = /(?:^|[#&])t=([-+0-9.eE]+)/.exec(location.hash);
      if (m && isFinite(Number(m[1]))) { pause(); seekTime(Number(m[1])); } else { seekRow(row); }
    }
    window.addEventListener("hashchange", fromHash);
    buildPlots();
    fromHash();
    document.body.dataset.ready = "1";
  }
})();
