// The report's zoomable time view: panels that share one time axis, drawn on canvases from
// the JSON in #zoom-data. Drag across a panel to zoom to that span, ctrl+wheel to zoom around
// the cursor, shift+wheel or the arrow buttons to pan, double-click or "whole record" to reset.
// Long records are drawn as a min/max envelope per pixel column, so 10^6 samples stay fast.
// Self-contained: no library, no network.
(function () {
  "use strict";
  var errors = [];
  window.addEventListener("error", function (e) {
    errors.push(String(e.message));
    document.body.setAttribute("data-js-errors", errors.join(" | "));
  });
  var source = document.getElementById("zoom-data");
  var count = source ? zoomView(JSON.parse(source.textContent)) : 0;

  // Where each plot landed, for a headless browser's check of the rendered page.
  var rects = [];
  document.querySelectorAll("canvas, svg").forEach(function (el, i) {
    var r = el.getBoundingClientRect();
    rects.push({
      what: el.tagName.toLowerCase(), index: i,
      x: Math.round(r.left + window.scrollX), y: Math.round(r.top + window.scrollY),
      w: Math.round(r.width), h: Math.round(r.height)
    });
  });
  document.getElementById("layout").textContent = JSON.stringify(rects);
  document.body.setAttribute("data-rendered", String(count));
})();

function zoomView(data) {
  "use strict";
  var PALETTE = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e"];
  var GREY = "#8c8c8c";
  var t = data.time;
  var n = t.length;
  var root = document.getElementById("zoom");
  var view = [t[0], t[n - 1]];
  var hover = null;
  var panels = [];

  function lowerBound(x) {
    var lo = 0, hi = n;
    while (lo < hi) {
      var mid = (lo + hi) >> 1;
      if (t[mid] < x) lo = mid + 1; else hi = mid;
    }
    return lo;
  }
  function fmt(v) {
    if (!isFinite(v)) return String(v);
    var a = Math.abs(v);
    if (a === 0) return "0";
    if (a >= 1e-3 && a < 1e5) return String(Number(v.toPrecision(4)));
    return v.toExponential(3);
  }
  function ticks(lo, hi, count) {
    var span = hi - lo;
    if (!(span > 0)) return [lo];
    var step = Math.pow(10, Math.floor(Math.log10(span / count)));
    var err = span / count / step;
    if (err >= 5) step *= 5; else if (err >= 2) step *= 2;
    var out = [];
    // Each tick a whole multiple of the step: no 0.30000000000000004, no −6.9e−18 for 0.
    for (var k = Math.ceil(lo / step); k * step <= hi + 1e-9 * span; k++) {
      out.push(Number((k * step).toPrecision(12)));
    }
    return out;
  }

  data.panels.forEach(function (p) {
    var wrap = document.createElement("div");
    wrap.className = "zoom-panel";
    var canvas = document.createElement("canvas");
    canvas.height = 260;
    wrap.appendChild(canvas);
    root.appendChild(wrap);
    var panel = { spec: p, canvas: canvas, drag: null };
    panels.push(panel);
    var L = 70, R = 10, T = 22, B = 34;
    panel.margins = { L: L, R: R, T: T, B: B };
    function xOf(ev) {
      var r = canvas.getBoundingClientRect();
      return ev.clientX - r.left;
    }
    function timeAt(px) {
      var w = canvas.width - L - R;
      return view[0] + (px - L) / w * (view[1] - view[0]);
    }
    canvas.addEventListener("mousedown", function (ev) {
      panel.drag = { from: xOf(ev), to: xOf(ev) };
    });
    canvas.addEventListener("mousemove", function (ev) {
      var x = xOf(ev);
      hover = timeAt(x);
      if (panel.drag) panel.drag.to = x;
      drawAll();
    });
    canvas.addEventListener("mouseleave", function () {
      hover = null;
      drawAll();
    });
    window.addEventListener("mouseup", function () {
      var d = panel.drag;
      panel.drag = null;
      if (d && Math.abs(d.to - d.from) > 4) {
        var a = timeAt(Math.min(d.from, d.to)), b = timeAt(Math.max(d.from, d.to));
        setView(a, b);
      } else {
        drawAll();
      }
    });
    canvas.addEventListener("dblclick", function () { setView(t[0], t[n - 1]); });
    canvas.addEventListener("wheel", function (ev) {
      // A plain wheel scrolls the page past the panels; ctrl or shift makes it the view's.
      if (!ev.ctrlKey && !ev.shiftKey) return;
      ev.preventDefault();
      var span = view[1] - view[0];
      if (ev.shiftKey) {
        var dx = (ev.deltaY > 0 ? 0.1 : -0.1) * span;
        setView(view[0] + dx, view[1] + dx);
        return;
      }
      var c = timeAt(xOf(ev));
      var k = ev.deltaY > 0 ? 1.25 : 0.8;
      setView(c - (c - view[0]) * k, c + (view[1] - c) * k);
    }, { passive: false });
  });

  function setView(a, b) {
    var full = t[n - 1] - t[0];
    var span = Math.min(Math.max(b - a, full * 1e-6, 1e-12), full);
    a = Math.max(t[0], Math.min(a, t[n - 1] - span));
    view = [a, a + span];
    document.getElementById("zoom-span").textContent =
      fmt(view[0]) + " … " + fmt(view[1]) + " s";
    drawAll();
  }

  function drawPanel(panel) {
    var canvas = panel.canvas, p = panel.spec, m = panel.margins;
    canvas.width = Math.max(300, root.clientWidth);
    var ctx = canvas.getContext("2d");
    var W = canvas.width, H = canvas.height, w = W - m.L - m.R, h = H - m.T - m.B;
    var i0 = Math.max(0, lowerBound(view[0]) - 1), i1 = Math.min(n, lowerBound(view[1]) + 1);
    var ymin = Infinity, ymax = -Infinity;
    p.series.forEach(function (s) {
      for (var i = i0; i < i1; i++) {
        var v = s.y[i];
        if (Number.isFinite(v)) { if (v < ymin) ymin = v; if (v > ymax) ymax = v; }
      }
    });
    if (!(ymax > ymin)) { ymin -= 1; ymax += 1; }
    var pad = 0.05 * (ymax - ymin);
    ymin -= pad; ymax += pad;
    var X = function (x) { return m.L + (x - view[0]) / (view[1] - view[0]) * w; };
    var Y = function (y) { return m.T + (ymax - y) / (ymax - ymin) * h; };
    ctx.fillStyle = "#fff";
    ctx.fillRect(0, 0, W, H);
    ctx.font = "12px sans-serif";
    ctx.strokeStyle = "#e4e4e4";
    ctx.fillStyle = "#333";
    ctx.lineWidth = 1;
    ticks(view[0], view[1], 8).forEach(function (v) {
      var x = Math.round(X(v)) + 0.5;
      ctx.beginPath(); ctx.moveTo(x, m.T); ctx.lineTo(x, m.T + h); ctx.stroke();
      ctx.textAlign = "center";
      ctx.fillText(fmt(v), x, m.T + h + 14);
    });
    ticks(ymin, ymax, 5).forEach(function (v) {
      var y = Math.round(Y(v)) + 0.5;
      ctx.beginPath(); ctx.moveTo(m.L, y); ctx.lineTo(m.L + w, y); ctx.stroke();
      ctx.textAlign = "right";
      ctx.fillText(fmt(v), m.L - 4, y + 4);
    });
    ctx.textAlign = "center";
    ctx.fillText(data.x_label, m.L + w / 2, H - 4);
    ctx.save();
    ctx.translate(12, m.T + h / 2);
    ctx.rotate(-Math.PI / 2);
    ctx.fillText(p.y_label, 0, 0);
    ctx.restore();
    ctx.strokeStyle = "#666";
    ctx.strokeRect(m.L + 0.5, m.T + 0.5, w, h);

    ctx.save();
    ctx.beginPath(); ctx.rect(m.L, m.T, w, h); ctx.clip();
    var colour = 0;
    p.series.forEach(function (s) {
      ctx.strokeStyle = s.reference ? GREY : PALETTE[colour++ % PALETTE.length];
      ctx.lineWidth = 1;
      ctx.beginPath();
      if (i1 - i0 > 2 * w) {
        // Min/max envelope per pixel column, joined column to column (a flat stretch is a
        // line, not a row of zero-length strokes).
        var col = -1, lo = 0, hi = 0, started = false;
        var flush = function () {
          if (col < 0) return;
          if (started) ctx.lineTo(col + 0.5, Y(lo)); else ctx.moveTo(col + 0.5, Y(lo));
          ctx.lineTo(col + 0.5, Y(hi));
          started = true;
        };
        for (var i = i0; i < i1; i++) {
          var c = Math.floor(X(t[i])), v = s.y[i];
          if (!Number.isFinite(v)) continue;
          if (c !== col) {
            flush();
            col = c; lo = v; hi = v;
          } else { if (v < lo) lo = v; if (v > hi) hi = v; }
        }
        flush();
      } else {
        var first = true;
        for (var j = i0; j < i1; j++) {
          var u = s.y[j];
          if (!Number.isFinite(u)) { first = true; continue; }
          if (first) ctx.moveTo(X(t[j]), Y(u)); else ctx.lineTo(X(t[j]), Y(u));
          first = false;
        }
      }
      ctx.stroke();
    });
    if (panel.drag) {
      ctx.fillStyle = "rgba(31,119,180,0.15)";
      var a = Math.min(panel.drag.from, panel.drag.to), b = Math.max(panel.drag.from, panel.drag.to);
      ctx.fillRect(a, m.T, b - a, h);
    }
    var readout = "";
    if (hover !== null && hover >= view[0] && hover <= view[1]) {
      var k = Math.min(n - 1, lowerBound(hover));
      var hx = Math.round(X(t[k])) + 0.5;
      ctx.strokeStyle = "#444";
      ctx.beginPath(); ctx.moveTo(hx, m.T); ctx.lineTo(hx, m.T + h); ctx.stroke();
      readout = "t = " + fmt(t[k]) + " s";
      p.series.forEach(function (s) { readout += "   " + s.name + " = " + fmt(s.y[k]); });
    }
    ctx.restore();
    // Legend, or the values under the cursor.
    ctx.textAlign = "left";
    ctx.fillStyle = "#333";
    if (readout) {
      ctx.fillText(readout, m.L, 14);
    } else {
      var x = m.L, ci = 0;
      p.series.forEach(function (s) {
        ctx.fillStyle = s.reference ? GREY : PALETTE[ci++ % PALETTE.length];
        ctx.fillRect(x, 7, 14, 3);
        ctx.fillStyle = "#333";
        ctx.fillText(s.name, x + 18, 14);
        x += 30 + ctx.measureText(s.name).width;
      });
    }
  }

  function drawAll() { panels.forEach(drawPanel); }

  document.getElementById("zoom-reset").addEventListener("click", function () {
    setView(t[0], t[n - 1]);
  });
  document.getElementById("zoom-left").addEventListener("click", function () {
    var s = view[1] - view[0]; setView(view[0] - 0.5 * s, view[1] - 0.5 * s);
  });
  document.getElementById("zoom-right").addEventListener("click", function () {
    var s = view[1] - view[0]; setView(view[0] + 0.5 * s, view[1] + 0.5 * s);
  });
  window.addEventListener("resize", drawAll);
  setView(t[0], t[n - 1]);
  return panels.length;
}
