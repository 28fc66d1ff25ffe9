/* pccl viewer: one trace (static page) or the interactive explorer (pccl serve).
 * Reads the trace document of pccl/traces.py (docs/trace-format.md) and
 * rebuilds every state from `initial` and the steps' typed changes.
 * The page's state is exposed in DOM attributes for tests and tools:
 * body[data-step], .robot[data-agent][data-x][data-y], #source[data-line],
 * #inspector[data-changed], #verdict[data-kind]. window.pcclViewer is the API. */
(function () {
  "use strict";
  var BOOT = window.PCCL_BOOT || { mode: "static", data: null };
  var SVGNS = "http://www.w3.org/2000/svg";
  var COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
    "#7f7f7f", "#bcbd22", "#17becf"];
  var ROWH = 20;

  /* ---------------------------------------------------------------- pure logic */

  function cellKey(cell) {               /* as traces.cell_name: waitTime[0], reqid, pos[1], time */
    var c = cell.cell;
    var name = cell["var"] !== undefined ? cell["var"] : (c === "position" ? "pos" : c);
    return cell.agent !== undefined && cell.agent !== null ? name + "[" + cell.agent + "]" : name;
  }

  var INTERNAL = { k: true, t0: true, obstacles: true };   /* codec.INTERNAL_CELLS: not shown as changes */
  function shown(changes) {
    return changes.filter(function (ch) { return !(ch.cell.agent !== undefined && INTERNAL[ch.cell.cell]); });
  }

  function applyChanges(s, changes) {    /* a new state; unchanged parts shared with s */
    var n = Object.assign({}, s), agents = null, copied = {};
    for (var j = 0; j < changes.length; j++) {
      var ch = changes[j], c = ch.cell;
      if (c.agent !== undefined) {
        if (!agents) { agents = s.agents.slice(); n.agents = agents; }
        var a = agents[c.agent];
        if (!copied[c.agent]) { a = Object.assign({}, a); agents[c.agent] = a; copied[c.agent] = true; }
        if (c["var"] !== undefined) {
          if (!copied["v" + c.agent]) { a.variables = Object.assign({}, a.variables); copied["v" + c.agent] = true; }
          a.variables[c["var"]] = ch["new"];
        } else {
          a[c.cell] = ch["new"];
        }
      } else if (c["var"] !== undefined) {
        if (!copied.sh) { n.shared = Object.assign({}, s.shared); copied.sh = true; }
        n.shared[c["var"]] = ch["new"];
      } else {
        n[c.cell] = ch["new"];
      }
    }
    return n;
  }

  function buildStates(doc) {
    var states = [doc.initial], s = doc.initial;
    for (var k = 0; k < doc.steps.length; k++) { s = applyChanges(s, doc.steps[k].changes); states.push(s); }
    return states;
  }

  /* every agent's pending computation per state: given, else from the next step it takes */
  function buildAt(doc, states, given) {
    if (given && given.length === states.length) return function (k, i) { return given[k][i]; };
    var n = doc.steps.length, N = doc.initial.agents.length, next = [];
    for (var i = 0; i < N; i++) {
      var arr = new Array(n + 1), cur = null;
      arr[n] = doc.final ? doc.final.agents[i].at : null;
      for (var k = n - 1; k >= 0; k--) {
        var st = doc.steps[k];
        if (st.agent === i && st.line !== null && st.line !== undefined) cur = "at line " + st.line;
        arr[k] = cur !== null ? cur : (k === 0 ? doc.initial.agents[i].at : "?");
      }
      if (n > 0 && arr[0] === "?") arr[0] = doc.initial.agents[i].at;
      next.push(arr);
    }
    return function (k, i) { return next[i][k]; };
  }

  /* values as pccl's text prints them (lang/values.format_value): a declared
   * type `ty` ({kind, elem}, viewer.py's types) says a list from a position;
   * without one, only the cells that are positions (position, target) are */
  var POS_TYPE = { kind: "pos", elem: null };
  function fmt(v, ty) {
    if (v === null || v === undefined) return "undefined";
    if (v === true) return "true";
    if (v === false) return "false";
    var kind = ty ? ty.kind : null;
    if (Array.isArray(v)) {
      if (kind === "pos" && v.every(function (x) { return typeof x === "number"; }))
        return "(" + v.map(pyFloat).join(", ") + ")";
      var elem = ty ? ty.elem : null;
      return "[" + v.map(function (x) { return fmt(x, elem); }).join(", ") + "]";
    }
    if (typeof v === "number") return kind === "float" || kind === "pos" ? pyFloat(v) : num(v);
    if (typeof v === "object") {
      if (v.status !== undefined) return v.status + (v.reason ? ": " + v.reason : "");
      return JSON.stringify(v);
    }
    return String(v);
  }
  function num(x) { return typeof x === "number" ? String(Math.round(x * 1000) / 1000) : String(x); }
  /* a float as Python's format_number: 4.0, 0.75, %.6g beyond */
  function pyFloat(x) {
    if (typeof x !== "number") return String(x);
    if (!isFinite(x)) return isNaN(x) ? "nan" : (x > 0 ? "inf" : "-inf");
    if (x === Math.trunc(x) && Math.abs(x) < 1e15) return x.toFixed(1);
    var e = x.toExponential(5), m = /^(-?[\d.]+)e([+-]\d+)$/.exec(e), X = +m[2];
    var strip = function (t) { return t.indexOf(".") >= 0 ? t.replace(/0+$/, "").replace(/\.$/, "") : t; };
    if (X < -4 || X >= 6) return strip(m[1]) + "e" + (X < 0 ? "-" : "+") + (Math.abs(X) < 10 ? "0" : "") + Math.abs(X);
    return strip(x.toFixed(5 - X));
  }
  /* the declared type of a change's cell (null: not known) */
  function cellType(types, cell) {
    if (cell.cell === "position" || cell.cell === "target") return POS_TYPE;
    if (!types || cell["var"] === undefined) return null;
    var t = cell.agent !== undefined ? types.agent : types.shared;
    return (t && t[cell["var"]]) || null;
  }

  function isPoint(v) {
    return Array.isArray(v) && v.length >= 2 && v.length <= 3 && v.every(function (x) { return typeof x === "number"; });
  }

  /* the model of one trace: states, per-agent trails, marks */
  function Trace(data) {
    var doc = data.trace;
    this.data = data; this.doc = doc;
    this.empty = !doc.initial;
    if (this.empty) return;
    this.states = buildStates(doc);
    this.n = doc.steps.length;
    this.N = doc.initial.agents.length;
    this.at = buildAt(doc, this.states, data.at);
    var res = doc.result || {};
    this.violation = res.violation || null;
    this.cycleStart = res.cycle_start !== undefined ? res.cycle_start : null;
    /* trails: [step, x, y] where a position changed; failures; targets */
    this.trails = []; this.fails = []; this.targets = [];
    for (var i = 0; i < this.N; i++) {
      var p = doc.initial.agents[i].position;
      this.trails.push([[0, p[0], p[1]]]);
    }
    for (var k = 0; k < this.n; k++) {
      var chs = doc.steps[k].changes;
      for (var j = 0; j < chs.length; j++) {
        var ch = chs[j], c = ch.cell;
        if (c.cell === "position") this.trails[c.agent].push([k + 1, ch["new"][0], ch["new"][1]]);
        else if (c.cell === "doReach_fail" && ch["new"] === true) {
          var q = this.states[k + 1].agents[c.agent].position;
          this.fails.push({ step: k + 1, agent: c.agent, x: q[0], y: q[1] });
        } else if (c.cell === "target" && ch["new"]) this.targets.push({ step: k + 1, agent: c.agent, p: ch["new"] });
      }
    }
    this.dests = [];                       /* initial List<ItemPosition>-like shared values */
    var sh = doc.initial.shared;
    for (var name in sh) {
      var v = sh[name];
      var ty = data.types ? data.types.shared[name] : null;
      var pts = ty ? ty.kind === "list" && !!ty.elem && ty.elem.kind === "pos" : Array.isArray(v) && v.every(isPoint);
      if (Array.isArray(v) && v.length && pts) v.forEach(function (pt) { this.dests.push(pt); }, this);
    }
  }
  Trace.prototype.culprits = function () {   /* agents to ring at the violating state */
    var v = this.violation, last = this.states[this.n], r = this.data.world.radius, out = [];
    if (!v) return out;
    if (v.agent !== null && v.agent !== undefined) return [v.agent];
    if (v.kind === "collision") {
      for (var i = 0; i < this.N; i++) for (var j = i + 1; j < this.N; j++) {
        var a = last.agents[i].position, b = last.agents[j].position;
        if (Math.hypot(a[0] - b[0], a[1] - b[1]) < 2 * r + 1e-9) { out.push(i); out.push(j); }
      }
      if (out.length) return out.filter(function (x, k) { return out.indexOf(x) === k; });
    }
    if (v.kind === "deadlock") {
      for (var m = 0; m < this.N; m++) if (last.agents[m].status.status !== "exited") out.push(m);
      return out;
    }
    for (var z = 0; z < this.N; z++) out.push(z);
    return out;
  };
  Trace.prototype.changedKeys = function (k) {
    if (k <= 0) return [];
    return shown(this.doc.steps[k - 1].changes).map(function (ch) { return cellKey(ch.cell); });
  };
  Trace.prototype.trailUpTo = function (i, k) {   /* points of agent i's path until state k */
    var t = this.trails[i], lo = 0, hi = t.length;
    while (lo < hi) { var mid = (lo + hi) >> 1; if (t[mid][0] <= k) lo = mid + 1; else hi = mid; }
    return t.slice(0, lo);
  };
  Trace.prototype.stepText = function (k, i) {    /* swimlane cell of agent i (or null: shared) at step k */
    var st = this.doc.steps[k - 1];
    var own = [], shared = [], types = this.data.types;
    shown(st.changes).forEach(function (ch) {
      var c = ch.cell, txt = cellKey(c).replace(/\[\d+\]$/, "") + "=" + fmt(ch["new"], cellType(types, c));
      if (c.agent !== undefined) { if (c.agent === i) own.push(txt); }
      else if (c.cell !== "time" && c.cell !== "phase") shared.push(txt);
    });
    if (i === null) {
      if (st.rule === "TIME ADVANCE") return "time advance → t=" + num(this.states[k].time);
      return shared.join(", ");
    }
    if (st.rule === "DOREACH INVOKE") return own.length ? "moves: " + own.join(", ") : "";
    if (st.agent !== i) return "";
    var text;
    if (st.rule === "EVENT SELECT") text = (st.event || "?") + "()";
    else if (st.line !== null && st.line !== undefined) text = "L" + st.line + " " + (st.source || "");
    else text = st.rule;
    if (st.branch) text += " → " + st.branch.taken;
    if (own.length) text += ": " + own.join(", ");
    return text;
  };

  /* ---------------------------------------------------------------- DOM helpers */

  function $(id) { return document.getElementById(id); }
  function el(tag, attrs, text) {
    var e = document.createElement(tag);
    for (var k in attrs || {}) e.setAttribute(k, attrs[k]);
    if (text !== undefined) e.textContent = text;
    return e;
  }
  function sv(tag, attrs, text) {
    var e = document.createElementNS(SVGNS, tag);
    for (var k in attrs || {}) e.setAttribute(k, attrs[k]);
    if (text !== undefined) e.textContent = text;
    return e;
  }
  function colour(i) { return COLOURS[i % COLOURS.length]; }

  /* a virtualised list: only the visible rows are in the DOM.  Rows wrap
   * (nothing is cut off): a row's height is estimated from its text
   * (`textOf(i)`: the longest cell's length over the characters a line of it
   * holds) until it is drawn, then measured, and the rows below move. */
  function VList(box, count, render, onclick, header, textOf, colPx) {
    this.box = box; this.count = count; this.render = render; this.cur = -1;
    this.textOf = textOf || null; this.colPx = colPx || null;
    box.textContent = "";
    this.head = header ? box.appendChild(header) : null;
    this.headH = header ? (header.offsetHeight || ROWH) : 0;
    this.spacer = box.appendChild(el("div", { "class": "vspacer" }));
    this.rows = {};
    this.estimate();
    var self = this;
    box.onscroll = function () { self.draw(); };
    box.onclick = function (e) {
      var r = e.target.closest(".vrow[data-index]");
      if (r) onclick(+r.getAttribute("data-index"));
    };
    this.draw();
  }
  VList.prototype.estimate = function () {   /* heights from the text, before rows are drawn */
    var n = this.count, h = new Float64Array(n), per = this.perLine();
    for (var i = 0; i < n; i++) {
      var lines = 1;
      if (this.textOf && per) {
        var cells = this.textOf(i);
        if (!Array.isArray(cells)) cells = [cells];
        cells.forEach(function (c, j) {
          var cap = Array.isArray(per) ? per[j] : per;
          if (cap > 0 && c) lines = Math.max(lines, Math.ceil(c.length / cap));
        });
      }
      h[i] = lines * ROWH;
    }
    this.h = h;
    this.layout();
  };
  VList.prototype.perLine = function () {    /* characters per line: one number, or one per column */
    var w = charWidth(this.box);
    if (!w) return 0;
    if (this.colPx) return this.colPx.map(function (px) { return Math.max(1, Math.floor((px - 10) / w)); });
    return Math.max(1, Math.floor(((this.box.clientWidth || 600) - 12) / w));
  };
  VList.prototype.layout = function () {
    var n = this.count, off = new Float64Array(n + 1);
    for (var i = 0; i < n; i++) off[i + 1] = off[i] + this.h[i];
    this.off = off;
    this.spacer.style.height = (off[n] + this.headH) + "px";
    for (var k in this.rows) this.rows[k].style.top = (off[k] + this.headH) + "px";
  };
  VList.prototype.indexAt = function (y) {   /* the row at offset y */
    var lo = 0, hi = this.count;
    while (lo < hi) { var mid = (lo + hi) >> 1; if (this.off[mid + 1] <= y) lo = mid + 1; else hi = mid; }
    return Math.min(lo, Math.max(0, this.count - 1));
  };
  VList.prototype.draw = function () {
    if (!this.count) return;
    var top = this.box.scrollTop, h = this.box.clientHeight || 300;
    var a = Math.max(0, this.indexAt(Math.max(0, top - this.headH)) - 5);
    var b = Math.min(this.count, this.indexAt(top + h) + 6);
    var keep = {}, moved = false;
    for (var i = a; i < b; i++) {
      keep[i] = true;
      var r = this.rows[i];
      if (!r) {
        r = this.render(i);
        r.classList.add("vrow");
        r.setAttribute("data-index", i);
        r.style.top = (this.off[i] + this.headH) + "px";
        this.box.appendChild(r);
        this.rows[i] = r;
        var real = r.offsetHeight;
        if (real && Math.abs(real - this.h[i]) > 0.5) { this.h[i] = real; moved = true; }
      }
      r.classList.toggle("cur", i === this.cur);
    }
    for (var k in this.rows) if (!keep[k]) { this.box.removeChild(this.rows[k]); delete this.rows[k]; }
    if (moved) this.layout();
  };
  VList.prototype.select = function (i) {
    this.cur = i;
    var top = this.off[i] || 0, h = this.box.clientHeight || 300;
    if (top < this.box.scrollTop || top + (this.h[i] || ROWH) + this.headH > this.box.scrollTop + h)
      this.box.scrollTop = Math.max(0, top - h / 3);
    this.draw();
  };
  var CHARW = {};
  function charWidth(box) {                  /* the width of a character of the list's (monospace) font */
    var f = getComputedStyle(box).font;
    if (CHARW[f]) return CHARW[f];
    var s = box.appendChild(el("span", { style: "position:absolute;visibility:hidden;white-space:pre" }, new Array(101).join("0")));
    var w = s.getBoundingClientRect().width / 100;
    box.removeChild(s);
    if (w > 0) CHARW[f] = w;
    return w;
  }

  /* ---------------------------------------------------------------- the viewer */

  var V = { k: 0, trace: null, playing: false, mode: BOOT.mode };
  window.pcclViewer = V;
  V.cellKey = cellKey; V.shown = shown; V.applyChanges = applyChanges; V.buildStates = buildStates; V.fmt = fmt;

  V.load = function (data) {
    V.data = data;
    V.trace = new Trace(data);
    var T = V.trace;
    $("title").textContent = data.title || "pccl";
    document.title = data.title || "pccl";
    drawVerdict();
    drawSource();
    if (T.empty) {
      $("picture").textContent = "no path to show: " + ((data.trace.result || {}).message || "");
      $("slider").max = 0;
      document.body.setAttribute("data-steps", "0");
      return;
    }
    $("slider").max = T.n;
    document.body.setAttribute("data-steps", String(T.n));
    document.body.setAttribute("data-agents", String(T.N));
    if (data.motion) buildArena(); else buildTimeline();
    buildSwimlane();
    buildSummary();
    buildPlot();
    buildWatch();
    V.goto(0, true);
  };

  function drawVerdict() {
    var res = V.data.trace.result || {}, v = res.violation, box = $("verdict");
    box.textContent = "";
    box.className = v ? "bad" : "";
    box.setAttribute("data-status", res.status || "");
    box.setAttribute("data-kind", v ? v.kind : "");
    box.setAttribute("data-name", v ? v.name : "");
    var line = res.message || (v ? v.message : res.status || "");
    box.appendChild(document.createTextNode(line));
    if (v && v.message && v.message !== line) box.appendChild(el("span", { "class": "note" }, v.message));
    if (res.cycle_start !== undefined && res.cycle_start !== null)
      box.appendChild(el("span", { "class": "note" }, "lasso: the steps after step " + res.cycle_start +
        " repeat forever (marked in the swimlane; playing loops them)"));
    if (res.witness) box.appendChild(el("span", { "class": "note" }, "witness of reachable " + res.witness.text));
    (V.data.notes || []).forEach(function (n) { box.appendChild(el("span", { "class": "note" }, n)); });
  }

  function drawSource() {
    var box = $("source"), src = V.data.source;
    box.textContent = "";
    V.srcLines = {};
    if (!src) { box.textContent = "(the program's source is not available)"; return; }
    $("source-title").textContent = "source: " + src.path;
    var v = V.data.trace.result && V.data.trace.result.violation;
    src.text.split("\n").forEach(function (t, j) {
      var d = el("div", { "class": "ln", "data-line": String(j + 1) }, t);
      if (v && v.line === j + 1) d.classList.add("vio");
      box.appendChild(d);
      V.srcLines[j + 1] = d;
    });
  }

  /* arena ------------------------------------------------------------ */
  function buildArena() {
    var T = V.trace, w = V.data.world, r = w.radius;
    var xs = [], ys = [];
    function ext(p) { xs.push(p[0]); ys.push(p[1]); }
    if (w.arena) { ext(w.arena[0]); ext(w.arena[1]); }
    w.obstacles.forEach(function (poly) { poly.forEach(ext); });
    T.trails.forEach(function (t) { t.forEach(function (q) { ext([q[1], q[2]]); }); });
    T.targets.forEach(function (t) { ext(t.p); });
    T.dests.forEach(ext);
    var m = 2 * r + 0.3;
    var x0 = Math.min.apply(null, xs) - m, x1 = Math.max.apply(null, xs) + m;
    var y0 = Math.min.apply(null, ys) - m, y1 = Math.max.apply(null, ys) + m;
    var W = x1 - x0, H = y1 - y0;
    V.unit = Math.max(W, H) / 100;
    var u = V.unit, L = 8 * u, B = 6 * u;      /* room for the axes' labels, left and below */
    var svg = sv("svg", { id: "arena", viewBox: [x0 - L, -y1, W + L, H + B].join(" "), "stroke-width": u * 0.3 });
    drawAxes(svg, x0, x1, y0, y1, u);
    if (w.arena) {
      var a = w.arena;
      svg.appendChild(sv("rect", { "class": "arena", x: a[0][0], y: -a[1][1], width: a[1][0] - a[0][0],
        height: a[1][1] - a[0][1], "stroke-width": u * 0.3 }));
    }
    w.obstacles.forEach(function (poly, j) {
      svg.appendChild(sv("polygon", { "class": "obstacle", "data-obstacle": j + 1,
        points: poly.map(function (p) { return p[0] + "," + (-p[1]); }).join(" "), "stroke-width": u * 0.3 }));
      var cx = 0, cy = 0;
      poly.forEach(function (p) { cx += p[0]; cy += p[1]; });
      svg.appendChild(sv("text", { x: cx / poly.length, y: -cy / poly.length, "font-size": u * 3,
        "text-anchor": "middle", "dominant-baseline": "central", fill: "#fff" }, String(j + 1)));
    });
    T.dests.forEach(function (p) {
      svg.appendChild(sv("path", { "class": "dest", d: star(p[0], -p[1], u * 2.2), "stroke-width": u * 0.2 }));
    });
    for (var i = 0; i < T.N; i++) {       /* start positions: dashed footprints */
      var p0 = T.states[0].agents[i].position;
      svg.appendChild(sv("circle", { "class": "start", cx: p0[0], cy: -p0[1], r: r, stroke: colour(i),
        "stroke-width": u * 0.3 }));
    }
    V.layer = svg.appendChild(sv("g", { id: "dynamic" }));
    V.robots = [];
    V.trailEls = []; V.headEls = []; V.targetEls = [];
    for (var k = 0; k < T.N; k++) {
      V.trailEls.push(V.layer.appendChild(sv("polyline", { "class": "trail", stroke: colour(k), "stroke-width": u * 0.5 })));
      V.headEls.push(V.layer.appendChild(sv("line", { "class": "heading", stroke: colour(k), "stroke-width": u * 0.3,
        "data-agent": k })));
      V.targetEls.push(V.layer.appendChild(sv("path", { "class": "target", stroke: colour(k), "stroke-width": u * 0.5,
        "data-agent": k })));
    }
    V.failLayer = V.layer.appendChild(sv("g", { id: "fails" }));
    for (var g = 0; g < T.N; g++) {
      var robot = sv("g", { "class": "robot", "data-agent": g });
      robot.appendChild(sv("circle", { r: r, fill: colour(g), "stroke-width": u * 0.3 }));
      robot.appendChild(sv("text", { "font-size": Math.min(r * 1.2, u * 4), "text-anchor": "middle",
        "dominant-baseline": "central" }, String(g)));
      robot.appendChild(sv("title", {}, "agent " + g));
      V.robots.push(V.layer.appendChild(robot));
    }
    V.ringLayer = V.layer.appendChild(sv("g", { id: "rings" }));
    V.spotLayer = V.layer.insertBefore(sv("g", { id: "spots" }), V.robots[0] || null);
    $("picture").textContent = "";
    $("picture").appendChild(svg);
    $("picture").appendChild(arenaLegend());
  }
  /* axes in the world's units: a light grid, ticks and their values */
  function tickStep(span) {
    var raw = span / 6, p = Math.pow(10, Math.floor(Math.log10(raw))), f = raw / p;
    return p * (f < 1.5 ? 1 : f < 3.5 ? 2 : f < 7.5 ? 5 : 10);
  }
  function drawAxes(svg, x0, x1, y0, y1, u) {
    var g = svg.appendChild(sv("g", { id: "axes", "font-size": u * 2.4, fill: "#666" }));
    var ax = g.appendChild(sv("g", { id: "axis-x" })), ay = g.appendChild(sv("g", { id: "axis-y" }));
    ax.appendChild(sv("line", { "class": "axis", x1: x0, x2: x1, y1: -y0, y2: -y0, "stroke-width": u * 0.25 }));
    ay.appendChild(sv("line", { "class": "axis", x1: x0, x2: x0, y1: -y0, y2: -y1, "stroke-width": u * 0.25 }));
    var sx = tickStep(x1 - x0), sy = tickStep(y1 - y0);
    for (var x = Math.ceil(x0 / sx) * sx; x <= x1 + 1e-9; x += sx) {
      var vx = +x.toPrecision(12);
      g.insertBefore(sv("line", { "class": "grid", x1: vx, x2: vx, y1: -y0, y2: -y1, "stroke-width": u * 0.12 }), ax);
      ax.appendChild(sv("line", { "class": "axis", x1: vx, x2: vx, y1: -y0, y2: -y0 + u, "stroke-width": u * 0.25 }));
      ax.appendChild(sv("text", { "class": "tick", x: vx, y: -y0 + 3.6 * u, "text-anchor": "middle", "data-value": vx }, num(vx)));
    }
    for (var y = Math.ceil(y0 / sy) * sy; y <= y1 + 1e-9; y += sy) {
      var vy = +y.toPrecision(12);
      g.insertBefore(sv("line", { "class": "grid", x1: x0, x2: x1, y1: -vy, y2: -vy, "stroke-width": u * 0.12 }), ax);
      ay.appendChild(sv("line", { "class": "axis", x1: x0 - u, x2: x0, y1: -vy, y2: -vy, "stroke-width": u * 0.25 }));
      ay.appendChild(sv("text", { "class": "tick", x: x0 - 1.6 * u, y: -vy, "text-anchor": "end",
        "dominant-baseline": "central", "data-value": vy }, num(vy)));
    }
    ax.appendChild(sv("text", { x: x1, y: -y0 + 3.6 * u, "text-anchor": "end", "font-style": "italic" }, "x"));
    ay.appendChild(sv("text", { x: x0 - 1.6 * u, y: -y1 + 1.5 * u, "text-anchor": "end", "font-style": "italic" }, "y"));
  }
  /* a legend under the picture: [[swatch element, words]] */
  function legend(items) {
    var box = el("div", { id: "legend", "class": "legend" });
    items.forEach(function (it) {
      var e = box.appendChild(el("span", { "class": "item", "data-legend": it[1] }));
      e.appendChild(it[0]);
      e.appendChild(el("span", {}, it[1]));
    });
    return box;
  }
  function swatch(draw) {                    /* a small SVG of one mark */
    var s = sv("svg", { width: 22, height: 14, viewBox: "-11 -7 22 14", "class": "swatch" });
    draw(s);
    return s;
  }
  function arenaLegend() {
    var items = [];
    for (var i = 0; i < V.trace.N; i++) (function (i) {
      items.push([swatch(function (s) { s.appendChild(sv("circle", { r: 6, fill: colour(i), stroke: "#222" })); }), "agent " + i]);
    })(i);
    items.push([swatch(function (s) { s.appendChild(sv("circle", { r: 5, fill: "none", stroke: "#555", "stroke-dasharray": "2 2" })); }), "start"]);
    items.push([swatch(function (s) { s.appendChild(sv("line", { x1: -10, x2: 10, y1: 0, y2: 0, stroke: "#555", "stroke-width": 2 })); }), "path so far"]);
    items.push([swatch(function (s) { s.appendChild(sv("path", { d: cross(0, 0, 4), stroke: "#555", "stroke-width": 2 })); }), "doReach target"]);
    if (V.trace.dests.length)
      items.push([swatch(function (s) { s.appendChild(sv("path", { d: star(0, 0, 6), fill: "#f9a825", stroke: "#8d6e00" })); }), "destination (input)"]);
    if (V.data.world.obstacles.length)
      items.push([swatch(function (s) { s.appendChild(sv("rect", { x: -8, y: -5, width: 16, height: 10, fill: "#9e9e9e" })); }), "obstacle"]);
    if (V.trace.fails.length)
      items.push([swatch(function (s) { s.appendChild(sv("path", { d: cross(0, 0, 5), stroke: "#c62828", "stroke-width": 2 })); }), "doReach failed"]);
    if (V.trace.violation)
      items.push([swatch(function (s) { s.appendChild(sv("circle", { r: 6, fill: "none", stroke: "#c62828", "stroke-width": 2 })); }), "agent in the violation"]);
    items.push([swatch(function (s) {
      s.appendChild(sv("circle", { r: 6, fill: "none", stroke: "#555", "stroke-dasharray": "1 1.5" }));
      s.appendChild(sv("circle", { cx: -3, r: 3, fill: colour(0) })); s.appendChild(sv("circle", { cx: 3, r: 3, fill: colour(1) }));
    }), "robots at one spot (drawn apart)"]);
    return legend(items);
  }
  function star(x, y, s) {
    var pts = [];
    for (var j = 0; j < 10; j++) {
      var a = Math.PI / 2 + j * Math.PI / 5, rr = j % 2 ? s * 0.4 : s;
      pts.push((x + rr * Math.cos(a)) + "," + (y - rr * Math.sin(a)));
    }
    return "M" + pts.join("L") + "Z";
  }
  function cross(x, y, s) {
    return "M" + (x - s) + "," + (y - s) + "L" + (x + s) + "," + (y + s) + "M" + (x - s) + "," + (y + s) + "L" + (x + s) + "," + (y - s);
  }

  function drawArena(k, frac) {
    var T = V.trace, st = T.states[k], u = V.unit, r = V.data.world.radius;
    var prev = frac !== undefined && k > 0 ? T.states[k - 1] : null;
    var at = [];
    for (var i0 = 0; i0 < T.N; i0++) {
      var p0 = st.agents[i0].position, xy = [p0[0], p0[1]];
      if (prev) {                          /* interpolate the motion of this step */
        var q0 = prev.agents[i0].position;
        xy = [q0[0] + (p0[0] - q0[0]) * frac, q0[1] + (p0[1] - q0[1]) * frac];
      }
      at.push(xy);
    }
    /* robots at one spot (closer than half a radius) are drawn apart, around
     * it, with a dotted ring marking the spot: none hides another */
    var drawn = at.map(function (xy) { return xy.slice(); }), spot = [];
    V.spotLayer.textContent = "";
    for (var a = 0; a < T.N; a++) {
      if (spot[a] !== undefined) continue;
      var grp = [a];
      for (var b = a + 1; b < T.N; b++)
        if (spot[b] === undefined && Math.hypot(at[a][0] - at[b][0], at[a][1] - at[b][1]) < r * 0.5) grp.push(b);
      grp.forEach(function (m) { spot[m] = grp.length; });
      if (grp.length < 2) continue;
      grp.forEach(function (m, j) {
        var ang = Math.PI / 2 + 2 * Math.PI * j / grp.length;
        drawn[m] = [at[a][0] + r * Math.cos(ang), at[a][1] + r * Math.sin(ang)];
      });
      V.spotLayer.appendChild(sv("circle", { "class": "spot", cx: at[a][0], cy: -at[a][1], r: r * 2.1,
        "stroke-width": u * 0.3, "data-agents": grp.join(",") }));
    }
    for (var i = 0; i < T.N; i++) {
      var ag = st.agents[i], p = ag.position, x = at[i][0], y = at[i][1];
      var robot = V.robots[i];
      robot.setAttribute("transform", "translate(" + drawn[i][0] + "," + (-drawn[i][1]) + ")");
      robot.setAttribute("data-stacked", String(spot[i]));
      robot.setAttribute("data-x", String(p[0]));
      robot.setAttribute("data-y", String(p[1]));
      robot.setAttribute("data-status", ag.status.status);
      robot.classList.toggle("stuck", ag.status.status === "stuck");
      var pts = T.trailUpTo(i, prev ? k - 1 : k).map(function (q) { return q[1] + "," + (-q[2]); });
      pts.push(x + "," + (-y));
      V.trailEls[i].setAttribute("points", pts.join(" "));
      var tgt = ag.target, he = V.headEls[i], te = V.targetEls[i];
      if (tgt && !ag.doReach_done && ag.status.status !== "exited") {
        he.setAttribute("x1", x); he.setAttribute("y1", -y); he.setAttribute("x2", tgt[0]); he.setAttribute("y2", -tgt[1]);
        he.style.display = "";
        te.setAttribute("d", cross(tgt[0], -tgt[1], u * 1.2));
        te.style.display = "";
        robot.setAttribute("data-target", tgt[0] + "," + tgt[1]);
      } else {
        he.style.display = "none"; te.style.display = "none";
        robot.removeAttribute("data-target");
      }
    }
    V.failLayer.textContent = "";
    T.fails.forEach(function (f) {
      if (f.step > k) return;
      var g = V.failLayer.appendChild(sv("g", { "class": "fail", "data-agent": f.agent, "data-step": f.step }));
      g.appendChild(sv("path", { d: cross(f.x, -f.y, r * 1.3), "stroke-width": u * 0.6 }));
      g.appendChild(sv("text", { x: f.x + r * 1.4, y: -f.y, "font-size": u * 2.6, fill: "#c62828" },
        "doReach failed (" + f.agent + ")"));
    });
    V.ringLayer.textContent = "";
    V.robots.forEach(function (rb) { rb.classList.remove("culprit"); });
    if (k === T.n && T.violation) {
      T.culprits().forEach(function (i) {
        var p = st.agents[i].position;
        V.robots[i].classList.add("culprit");
        V.ringLayer.appendChild(sv("circle", { "class": "ring", cx: p[0], cy: -p[1], r: r * 1.6,
          "stroke-width": u * 0.7, "data-agent": i }));
      });
    }
  }

  /* timeline (programs that do not move) ----------------------------- */
  function buildTimeline() {
    var T = V.trace, W = 900, laneH = 34, top = 18, left = 70;
    var H = top + T.N * laneH + 24;
    var svg = sv("svg", { id: "timeline", viewBox: "0 0 " + (W + left + 10) + " " + H });
    var sx = function (k) { return left + (T.n ? k * W / T.n : 0); };
    V.sx = sx;
    var events = {}, nev = 0;
    function evColour(name) {
      if (name === null) return "#bdbdbd";
      if (events[name] === undefined) events[name] = nev++;
      return COLOURS[(events[name] + 2) % COLOURS.length];
    }
    for (var i = 0; i < T.N; i++) {
      var y = top + i * laneH;
      svg.appendChild(sv("text", { "class": "lane-label", x: 4, y: y + laneH / 2, "dominant-baseline": "central" }, "agent " + i));
      svg.appendChild(sv("line", { x1: left, x2: left + W, y1: y + laneH / 2, y2: y + laneH / 2, stroke: "#eee" }));
    }
    /* bars: runs of an agent's steps within one event block */
    var open = [];
    for (var a = 0; a < T.N; a++) open.push(null);
    function close(a, endK) {
      var o = open[a];
      if (!o) return;
      var x = sx(o.from - 1), w = Math.max(1.5, sx(endK) - x);
      var bar = sv("rect", { "class": "tl-bar", x: x, y: top + a * laneH + 6, width: w, height: laneH - 12,
        fill: evColour(o.event), "data-agent": a, "data-event": o.event || "" });
      bar.appendChild(sv("title", {}, "agent " + a + ": " + (o.event || "idle") + " (steps " + o.from + "–" + endK + ")"));
      svg.appendChild(bar);
      if (o.event && sx(endK) - x > 40)
        svg.appendChild(sv("text", { x: x + 3, y: top + a * laneH + laneH / 2, "font-size": 10, fill: "#fff",
          "dominant-baseline": "central" }, o.event));
      open[a] = null;
    }
    var ticks = 0;
    for (var k = 1; k <= T.n; k++) {
      var st = T.doc.steps[k - 1], ag = st.agent;
      if (st.rule === "TIME ADVANCE") {
        if (ticks++ < 400) {
          svg.appendChild(sv("line", { x1: sx(k), x2: sx(k), y1: top - 4, y2: H - 20, stroke: "#e0e0e0" }));
          svg.appendChild(sv("text", { x: sx(k), y: H - 6, "font-size": 9, "text-anchor": "middle", fill: "#777" },
            "t=" + num(T.states[k].time)));
        }
        continue;
      }
      if (ag === null || ag === undefined) continue;
      var ev = st.rule === "IDLE" ? null : st.event;
      if (st.rule === "EVENT SELECT" || st.rule === "IDLE" || !open[ag] || open[ag].event !== ev) {
        close(ag, k - 1);
        open[ag] = { from: k, event: ev };
      }
      open[ag].last = k;
      if (st.rule === "EXIT") close(ag, k);
    }
    for (var b = 0; b < T.N; b++) if (open[b]) close(b, open[b].last);
    if (T.violation) {
      T.culprits().forEach(function (i) {
        svg.appendChild(sv("circle", { "class": "tl-bad", cx: sx(T.n), cy: top + i * laneH + laneH / 2, r: 6,
          "data-agent": i }));
      });
    }
    V.cursor = svg.appendChild(sv("line", { "class": "tl-cursor", y1: top - 6, y2: H - 20 }));
    V.laneState = [];
    for (var c = 0; c < T.N; c++)
      V.laneState.push(svg.appendChild(sv("g", { "class": "lane", "data-agent": c })));
    svg.addEventListener("click", function (e) {
      var pt = svg.createSVGPoint(); pt.x = e.clientX; pt.y = e.clientY;
      var p = pt.matrixTransform(svg.getScreenCTM().inverse());
      V.goto(Math.round((p.x - left) * T.n / W));
    });
    $("picture").textContent = "";
    $("picture").appendChild(svg);
    /* the legend: each event's colour, idle, the cursor, the violation's mark */
    var items = Object.keys(events).sort(function (x, y) { return events[x] - events[y]; }).map(function (name) {
      return [swatch(function (s) { s.appendChild(sv("rect", { x: -9, y: -5, width: 18, height: 10, fill: evColour(name) })); }),
        "event " + name];
    });
    items.push([swatch(function (s) { s.appendChild(sv("rect", { x: -9, y: -5, width: 18, height: 10, fill: evColour(null) })); }),
      "idle (no guard holds)"]);
    items.push([swatch(function (s) { s.appendChild(sv("line", { x1: 0, x2: 0, y1: -7, y2: 7, stroke: "#000", "stroke-width": 2 })); }),
      "the shown step"]);
    items.push([swatch(function (s) { s.appendChild(sv("line", { x1: 0, x2: 0, y1: -7, y2: 7, stroke: "#e0e0e0", "stroke-width": 2 })); }),
      "time advances (t= below)"]);
    if (T.violation)
      items.push([swatch(function (s) { s.appendChild(sv("circle", { r: 5, fill: "#c62828" })); }), "agent in the violation"]);
    $("picture").appendChild(legend(items));
    $("picture").appendChild(el("div", { "class": "note" }, "x: the trace's steps (one bar: an agent's steps in one event block); one lane per agent"));
  }
  function drawTimeline(k) {
    var T = V.trace, x = V.sx(k);
    V.cursor.setAttribute("x1", x); V.cursor.setAttribute("x2", x);
    V.cursor.setAttribute("data-step", k);
    V.laneState.forEach(function (g, i) {
      var ag = T.states[k].agents[i];
      g.setAttribute("data-status", ag.status.status);
      g.setAttribute("data-at", T.at(k, i));
    });
  }

  /* swimlane and run summary ------------------------------------------ */
  function buildSwimlane() {
    var T = V.trace, cols = ["#", "t"], box = $("swimlane");
    for (var i = 0; i < T.N; i++) cols.push("agent " + i);
    cols.push("shared");
    /* column widths in pixels: # and t as wide as their longest value, the
     * agents' and the shared one sharing the rest; cells wrap, never cut */
    var cw = charWidth(box) || 7, W = Math.max(300, (box.clientWidth || 600) - 2);
    var wNum = Math.ceil((String(T.n).length + 1) * cw + 10), wT = Math.ceil(Math.max(2, num(T.states[T.n].time).length + 1) * cw + 10);
    var rest = Math.max((T.N + 1) * 8 * cw, W - wNum - wT), each = Math.floor(rest / (T.N + 1));
    var widths = [wNum, wT];
    for (var j = 0; j <= T.N; j++) widths.push(each);
    function row(cells) {
      var r = el("div");
      cells.forEach(function (c, j) {
        var s = r.appendChild(el("span", { "class": "cell" }, c));
        s.style.flex = "0 0 " + widths[j] + "px";
        s.style.width = widths[j] + "px";
      });
      return r;
    }
    function cellsOf(k) {
      var cells = [String(k), num(T.states[k > 0 ? k - 1 : 0].time)];
      if (k === 0) {
        for (var a = 0; a < T.N; a++) cells.push("initial: pos " + fmt(T.states[0].agents[a].position, POS_TYPE));
        cells.push(Object.keys(T.doc.initial.shared).map(function (n) {
          return n + "=" + fmt(T.doc.initial.shared[n], cellType(V.data.types, { "var": n }));
        }).join(", "));
      } else {
        for (var b = 0; b < T.N; b++) cells.push(T.stepText(k, b));
        cells.push(T.stepText(k, null));
      }
      return cells;
    }
    var head = row(cols);
    head.className = "vrow vhead";
    V.swim = new VList(box, T.n + 1, function (k) {
      var r = row(cellsOf(k));
      r.setAttribute("data-step", k);
      if (T.cycleStart !== null && k > T.cycleStart) r.classList.add("cycle");
      if (k === T.n && T.violation) r.classList.add("bad");
      return r;
    }, function (k) { V.goto(k); }, head, cellsOf, widths);
  }

  /* the "time steps" panel: one line per time step, as `pccl run` prints its
   * summary: the initial state, then the state after each DOREACH INVOKE (the
   * environment's step that ends a time step), identical consecutive lines
   * folded.  The CLI's own lines when the page has them (data.text). */
  function buildSummary() {
    var T = V.trace, box = $("summary");
    var rows = V.data.text ? V.data.text.summary.map(function (r) { return { k: r[0], text: r[1].trim() }; })
      : summaryRows(T);
    V.times = rows.map(function (r) { return r.k; });
    if (rows.length < 2 && !V.data.motion) { box.hidden = true; V.sum = null; return; }
    box.hidden = false;
    V.sum = new VList($("summary-list"), rows.length, function (j) {
      var r = el("div", { "data-step": rows[j].k, "data-text": rows[j].text });
      r.appendChild(el("span", {}, rows[j].text));
      return r;
    }, function (j) { V.goto(rows[j].k); }, null, function (j) { return rows[j].text; });
  }
  function summaryRows(T) {              /* the page's own wording (no model: a trace as recorded) */
    var ks = [0], rows = [], types = V.data.types;
    for (var k = 1; k <= T.n; k++) if (T.doc.steps[k - 1].rule === "DOREACH INVOKE") ks.push(k);
    var prev = null;
    ks.forEach(function (k) {
      var st = T.states[k];
      var parts = st.agents.map(function (ag, i) {
        return "a" + i + " " + fmt(ag.position, POS_TYPE) + (ag.status.status === "running" ? "" : " " + fmt(ag.status));
      });
      if (prev !== null) {
        var ch = [];
        Object.keys(st.shared).forEach(function (n) {
          if (JSON.stringify(st.shared[n]) !== JSON.stringify(prev.shared[n]))
            ch.push(n + "=" + fmt(st.shared[n], cellType(types, { "var": n })));
        });
        st.agents.forEach(function (ag, i) {
          Object.keys(ag.variables).forEach(function (n) {
            if (JSON.stringify(ag.variables[n]) !== JSON.stringify(prev.agents[i].variables[n]))
              ch.push(n + "[" + i + "]=" + fmt(ag.variables[n], cellType(types, { agent: i, "var": n })));
          });
        });
        if (ch.length) parts.push(ch.join("; "));
      }
      var text = parts.join("  "), last = rows[rows.length - 1];
      if (last && last.body === text) { last.count++; last.t1 = st.time; }
      else rows.push({ k: k, body: text, t0: st.time, t1: st.time, count: 1 });
      prev = st;
    });
    return rows.map(function (r) {
      return { k: r.k, text: r.count === 1 ? "t=" + num(r.t0) + ": " + r.body :
        "t=" + num(r.t0) + "–" + num(r.t1) + ": " + r.body + " (" + r.count + " identical time steps)" };
    });
  }

  /* plot of chosen variables over the steps ------------------------- */
  function plotValue(v) { return v === true ? 1 : v === false ? 0 : typeof v === "number" && isFinite(v) ? v : null; }
  function plotSeries() {                /* [{name, get(state)}]: every number or bool variable */
    var T = V.trace, out = [{ name: "time", get: function (s) { return s.time; } }], s0 = T.states[0];
    function plottable(get) { return T.states.some(function (s) { return plotValue(get(s)) !== null; }); }
    Object.keys(s0.shared).forEach(function (n) {
      var get = function (s) { return s.shared[n]; };
      if (plottable(get)) out.push({ name: n, get: get });
    });
    for (var i = 0; i < T.N; i++) Object.keys(s0.agents[i].variables).forEach(function (n) {
      var ii = i, get = function (s) { return s.agents[ii].variables[n]; };
      if (plottable(get)) out.push({ name: n + "[" + ii + "]", get: get });
    });
    (V.data.watch || []).forEach(function (w) {
      if (w.numbers.some(function (x) { return x !== null; }))
        out.push({ name: w.text, values: w.numbers });
    });
    return out;
  }
  function buildPlot() {
    var sel = $("plot-vars");
    V.plotSeries = plotSeries();
    sel.textContent = "";
    V.plotSeries.forEach(function (p, j) { sel.appendChild(el("option", { value: String(j) }, p.name)); });
    sel.onchange = function () { drawPlot(); };
    drawPlot();
  }
  /* draw the chosen series: one polyline each (data-values: the values, step 0..n) */
  function drawPlot() {
    var T = V.trace, box = $("plot-area"), chosen = [];
    [].forEach.call($("plot-vars").selectedOptions, function (o) { chosen.push(V.plotSeries[+o.value]); });
    box.textContent = "";
    V.plotCursor = null;
    if (!chosen.length) { box.appendChild(el("div", { "class": "note" }, "(no variable chosen)")); return; }
    var W = 600, H = 160, left = 44, bottom = 18, lo = Infinity, hi = -Infinity;
    var series = chosen.map(function (p) {
      var ys = p.values ? p.values.slice() : T.states.map(function (s) { return plotValue(p.get(s)); });
      ys.forEach(function (y) { if (y !== null) { lo = Math.min(lo, y); hi = Math.max(hi, y); } });
      return { name: p.name, ys: ys };
    });
    if (!isFinite(lo)) { lo = 0; hi = 1; }
    if (hi === lo) { hi += 1; lo -= 1; }
    var sx = function (k) { return left + (T.n ? k * (W - left - 6) / T.n : 0); };
    var sy = function (y) { return 6 + (hi - y) * (H - bottom - 12) / (hi - lo); };
    var svg = sv("svg", { id: "plot-svg", viewBox: "0 0 " + W + " " + H });
    svg.appendChild(sv("line", { x1: left, x2: left, y1: 6, y2: H - bottom, stroke: "#999" }));
    svg.appendChild(sv("line", { x1: left, x2: W - 6, y1: H - bottom, y2: H - bottom, stroke: "#999" }));
    [lo, (lo + hi) / 2, hi].forEach(function (y) {
      svg.appendChild(sv("text", { x: left - 4, y: sy(y), "font-size": 10, "text-anchor": "end", "dominant-baseline": "central", fill: "#666" }, num(y)));
    });
    svg.appendChild(sv("text", { x: left, y: H - 4, "font-size": 10, fill: "#666" }, "step 0"));
    svg.appendChild(sv("text", { x: W - 6, y: H - 4, "font-size": 10, "text-anchor": "end", fill: "#666" }, "step " + T.n));
    var leg = [];
    series.forEach(function (p, j) {
      var pts = [], prev = null;
      p.ys.forEach(function (y, k) {            /* a step function: the value holds until the next step */
        if (y === null) return;
        if (prev !== null) pts.push(sx(k) + "," + sy(prev));
        pts.push(sx(k) + "," + sy(y)); prev = y;
      });
      svg.appendChild(sv("polyline", { "class": "plot-line", fill: "none", stroke: COLOURS[j % COLOURS.length], "stroke-width": 1.5,
        points: pts.join(" "), "data-name": p.name, "data-values": JSON.stringify(p.ys) }));
      leg.push([swatch(function (s) { s.appendChild(sv("line", { x1: -10, x2: 10, y1: 0, y2: 0, stroke: COLOURS[j % COLOURS.length], "stroke-width": 2 })); }), p.name]);
    });
    V.plotCursor = svg.appendChild(sv("line", { "class": "tl-cursor", y1: 6, y2: H - bottom }));
    V.plotSx = sx;
    svg.addEventListener("click", function (e) {
      var pt = svg.createSVGPoint(); pt.x = e.clientX; pt.y = e.clientY;
      var q = pt.matrixTransform(svg.getScreenCTM().inverse());
      V.goto(Math.round((q.x - left) * T.n / (W - left - 6)));
    });
    box.appendChild(svg);
    var lg = legend(leg); lg.id = "plot-legend"; box.appendChild(lg);
    drawPlotCursor(V.k);
  }
  function drawPlotCursor(k) {
    if (!V.plotCursor) return;
    var x = V.plotSx(k);
    V.plotCursor.setAttribute("x1", x); V.plotCursor.setAttribute("x2", x);
    V.plotCursor.setAttribute("data-step", String(k));
  }

  /* watched expressions ------------------------------------------------
   * Their values are pccl's: evaluated by pccl (the compiler that evaluates
   * invariants) in every state of the path, ahead of time (--watch) or by
   * pccl serve when asked (/api/watch); the page only shows them: it never
   * evaluates what a user types. */
  function buildWatch() {
    var tbl = $("watch-table"), ws = V.data.watch || [];
    tbl.textContent = "";
    V.watchCells = [];
    ws.forEach(function (w, j) {
      var tr = tbl.appendChild(el("tr", { "data-expr": w.text, "data-index": j }));
      tr.appendChild(el("td", { "class": "expr", title: "type " + w.type }, w.text));
      V.watchCells.push(tr.appendChild(el("td", { "class": "val" })));
      if (BOOT.mode === "serve") {
        var b = el("button", { "class": "unwatch", title: "stop watching" }, "×");
        b.onclick = function () { act("/api/unwatch", { index: j }); };
        tr.appendChild(el("td")).appendChild(b);
      }
    });
    if (!ws.length) tbl.appendChild(el("tr")).appendChild(el("td", { "class": "note" },
      BOOT.mode === "serve" ? "(none yet: type one above)" : "(none: write the page with --watch EXPR)"));
  }
  function drawWatch(k) {
    (V.data.watch || []).forEach(function (w, j) {
      var td = V.watchCells[j], v = w.values[k];
      td.textContent = "";
      td.parentNode.setAttribute("data-value", v);
      var ch = k > 0 && w.values[k - 1] !== v;
      td.parentNode.classList.toggle("changed", ch);
      if (ch) td.appendChild(el("span", { "class": "old" }, w.values[k - 1]));
      td.appendChild(document.createTextNode(v));
    });
  }
  function normExpr(t) { return String(t).replace(/\s+/g, " ").trim(); }
  function wireWatch() {
    function go() {
      var text = $("expr-input").value, msg = $("expr-msg");
      msg.textContent = ""; msg.className = "";
      if (!normExpr(text)) return;
      if (BOOT.mode === "serve") {
        api("/api/watch", { expr: text }).then(function (j) { V.receive(j); $("expr-input").value = ""; })
          .catch(function (e) { msg.textContent = e.message; msg.className = "bad"; });
        return;
      }
      var ws = V.data.watch || [], found = -1;
      ws.forEach(function (w, j) { if (normExpr(w.text) === normExpr(text)) found = j; });
      if (found >= 0) {
        var tr = $("watch-table").querySelector('tr[data-index="' + found + '"]');
        tr.classList.add("flash"); setTimeout(function () { tr.classList.remove("flash"); }, 800);
        return;
      }
      msg.textContent = "this page shows the expressions pccl evaluated when it wrote it (it never evaluates " +
        "text itself): write it again with --watch '" + text + "' (pccl run, explore or view), or use pccl serve, " +
        "which evaluates any expression you type";
    }
    $("expr-go").onclick = go;
    $("expr-input").onkeydown = function (e) { if (e.key === "Enter") { go(); e.preventDefault(); } };
  }

  /* inspector --------------------------------------------------------- */
  function drawInspector(k) {
    var T = V.trace, st = T.states[k], box = $("inspector"), types = V.data.types;
    var changed = {}, old = {};
    if (k > 0) shown(T.doc.steps[k - 1].changes).forEach(function (ch) { changed[cellKey(ch.cell)] = true; old[cellKey(ch.cell)] = ch.old; });
    if (k > 0) for (var a = 0; a < T.N; a++) {
      if (T.at(k, a) !== T.at(k - 1, a)) { changed["at[" + a + "]"] = true; old["at[" + a + "]"] = T.at(k - 1, a); }
    }
    var tbl = el("table"), keys = [];
    function group(t, cls) { var r = tbl.appendChild(el("tr", { "class": "group " + (cls || "") })); r.appendChild(el("td", { colspan: 2 }, t)); }
    /* a row: `builtin` rows are the configuration's own cells, labelled in
     * words (never a program's name); the others a program's variables */
    function add(key, label, v, ty, builtin, title) {
      var raw = ty === "raw", text = raw ? v : fmt(v, ty);
      var r = tbl.appendChild(el("tr", { "data-cell": key, "data-value": text, "class": builtin ? "builtin" : "var" }));
      r.appendChild(el("td", title ? { title: title } : {}, label));
      var td = r.appendChild(el("td"));
      if (changed[key]) {
        r.classList.add("changed");
        keys.push(key);
        td.appendChild(el("span", { "class": "old" }, raw ? old[key] : fmt(old[key], ty)));
      }
      td.appendChild(document.createTextNode(text));
    }
    group("configuration");
    add("time", "time", st.time, null, true);
    add("phase", "phase", st.phase, "raw", true);
    add("lockQueue", "lock queue", st.lockQueue, null, true);
    if (st.env !== null && st.env !== undefined) add("env", "environment", st.env, null, true);
    var sh = Object.keys(st.shared);
    if (sh.length) { group("shared variables"); sh.forEach(function (n) { add(n, n, st.shared[n], cellType(types, { "var": n })); }); }
    for (var i = 0; i < T.N; i++) {
      var ag = st.agents[i], s = "[" + i + "]";
      group("agent " + i);
      add("at" + s, "pending computation", T.at(k, i), "raw", true,
        "what the agent runs next (the paper's k cell)");
      add("status" + s, "status", ag.status, null, true);
      add("counter" + s, "counter", ag.counter, null, true);
      add("lockState" + s, "lock", ag.lockState, "raw", true);
      add("pos" + s, "position", ag.position, POS_TYPE, true);
      add("target" + s, "target", ag.target, POS_TYPE, true);
      add("doReach_done" + s, "doReach done", ag.doReach_done, null, true);
      add("doReach_fail" + s, "doReach failed", ag.doReach_fail, null, true);
      var names = Object.keys(ag.variables);
      if (names.length) group("agent " + i + " variables", "sub");
      for (var n in ag.variables) add(n + s, n, ag.variables[n], cellType(types, { agent: i, "var": n }));
    }
    box.textContent = "";
    var bad = k === T.n && T.violation;
    box.classList.toggle("violating", !!bad);
    box.setAttribute("data-violating", bad ? "true" : "false");
    if (bad) box.appendChild(el("div", { "class": "banner", id: "violating" },
      "violating state: " + T.violation.message));
    else if (k === T.n && T.cycleStart !== null)
      box.appendChild(el("div", { "class": "banner" }, "equal to the state after step " + T.cycleStart + ": the cycle closes"));
    box.appendChild(tbl);
    box.setAttribute("data-changed", keys.slice().sort().join(","));
    $("state-label").textContent = k === 0 ? "(initial)" : "after step " + k;
  }

  /* the step panel: the step as the CLI prints it (run --trace, a
   * counterexample), the CLI's own text when the page has it */
  function drawStepInfo(k) {
    var T = V.trace, box = $("stepinfo"), types = V.data.types;
    box.textContent = "";
    if (k === 0) { box.appendChild(el("div", { id: "steptext" }, "initial state, t=" + num(T.states[0].time))); return; }
    var st = T.doc.steps[k - 1], text;
    if (V.data.text) text = V.data.text.steps[k - 1];
    else {
      var who = st.agent === null || st.agent === undefined ? "system" : "agent " + st.agent;
      text = pad(String(k), 4, true) + ". t=" + num(st.time) + "  " + pad(who, 8) + "  " + pad(st.rule, 16) +
        (st.event ? "  [" + st.event + "]" : "") + (st.line ? "  line " + st.line + ": " + (st.source || "") : "");
      var ch = shown(st.changes).filter(function (c) { return c.cell.cell !== "phase"; }).map(function (c) {
        var ty = cellType(types, c.cell);
        return cellKey(c.cell) + " " + fmt(c.old, ty) + " -> " + fmt(c["new"], ty);
      });
      if (ch.length) text += "\n        " + ch.join(", ");
    }
    box.appendChild(el("div", { id: "steptext" }, text));
    var extra = [];
    if (st.outcome !== undefined) extra.push("outcome " + st.outcome);
    if (st.branch) extra.push("→ " + st.branch.taken);
    if (extra.length) box.appendChild(el("div", { "class": "note" }, extra.join("  ")));
  }
  function pad(t, n, right) { while (t.length < n) t = right ? " " + t : t + " "; return t; }

  function drawSourceLine(k) {
    var box = $("source"), T = V.trace;
    if (V.curLine) { V.curLine.classList.remove("cur"); V.curLine.style.borderLeftColor = ""; V.curLine = null; }
    var st = k > 0 ? T.doc.steps[k - 1] : null;
    var line = st && st.line ? st.line : null;
    box.setAttribute("data-line", line === null ? "" : String(line));
    box.setAttribute("data-agent", st && st.agent !== null && st.agent !== undefined ? String(st.agent) : "");
    if (line !== null && V.srcLines && V.srcLines[line]) {
      var d = V.srcLines[line];
      d.classList.add("cur");
      if (st.agent !== null && st.agent !== undefined) d.style.borderLeftColor = colour(st.agent);
      V.curLine = d;
      var top = d.offsetTop - box.offsetTop;
      if (top < box.scrollTop || top > box.scrollTop + box.clientHeight - 20) box.scrollTop = Math.max(0, top - box.clientHeight / 3);
    }
  }

  V.goto = function (k, force) {
    var T = V.trace;
    if (!T || T.empty) return;
    k = Math.max(0, Math.min(T.n, k | 0));
    if (k === V.k && !force) return;
    V.k = k;
    render(k);
  };
  function render(k) {
    var T = V.trace;
    document.body.setAttribute("data-step", String(k));
    $("slider").value = k;
    $("where").textContent = "step " + k + " / " + T.n + "  t=" + num(T.states[k].time);
    if (V.data.motion) drawArena(k); else drawTimeline(k);
    drawInspector(k);
    drawStepInfo(k);
    drawPlotCursor(k);
    drawWatch(k);
    drawSourceLine(k);
    V.swim.select(k);
    if (V.sum) {
      var j = 0;
      while (j + 1 < V.times.length && V.times[j + 1] <= k) j++;
      V.sum.select(j);
    }
    if (BOOT.mode === "static" && window.history && history.replaceState) {
      try { history.replaceState(null, "", "#step=" + k); } catch (e) { /* file: URLs in some browsers */ }
    }
    if (V.onrender) V.onrender(k);
  }

  /* playback: one step per 1/speed s, motion interpolated within the step */
  V.play = function () {
    var T = V.trace;
    if (!T || T.empty || V.playing) return;
    if (V.k >= T.n) V.goto(T.cycleStart !== null ? T.cycleStart : 0);
    V.playing = true;
    $("play").textContent = "pause";
    var t0 = null;
    function frame(ts) {
      if (!V.playing) return;
      if (t0 === null) t0 = ts;
      var dur = 1000 / (+$("speed").value || 5), f = (ts - t0) / dur;
      if (f >= 1) {
        t0 = ts;
        if (V.k >= T.n) {
          if (T.cycleStart !== null && T.cycleStart < T.n) V.goto(T.cycleStart);
          else { V.pause(); return; }
        } else {
          V.goto(V.k + 1);
          if (V.data.motion) drawArena(V.k, 0);
        }
      } else if (V.data.motion && V.k > 0) {
        drawArena(V.k, f);
      }
      requestAnimationFrame(frame);
    }
    requestAnimationFrame(frame);
  };
  V.pause = function () {
    if (!V.playing) return;
    V.playing = false;
    $("play").textContent = "play";
    render(V.k);
  };
  V.next = function () { V.pause(); V.goto(V.k + 1); };
  V.prev = function () { V.pause(); V.goto(V.k - 1); };
  V.state = function (k) { return V.trace.states[k === undefined ? V.k : k]; };

  function wire() {
    $("first").onclick = function () { V.pause(); V.goto(0); };
    $("last").onclick = function () { V.pause(); V.goto(V.trace ? V.trace.n : 0); };
    $("prev").onclick = V.prev;
    $("next").onclick = V.next;
    $("play").onclick = function () { if (V.playing) V.pause(); else V.play(); };
    $("slider").oninput = function () { V.pause(); V.goto(+this.value); };
    document.addEventListener("keydown", function (e) {
      var t = e.target && e.target.tagName;
      if (t === "INPUT" || t === "SELECT" || t === "TEXTAREA") return;
      if (e.key === "ArrowRight") { V.next(); e.preventDefault(); }
      else if (e.key === "ArrowLeft") { V.prev(); e.preventDefault(); }
      else if (e.key === "Home") { V.pause(); V.goto(0); e.preventDefault(); }
      else if (e.key === "End") { V.pause(); V.goto(V.trace.n); e.preventDefault(); }
      else if (e.key === " ") { if (V.playing) V.pause(); else V.play(); e.preventDefault(); }
    });
  }

  function hashStep() {
    var m = /step=(\d+)/.exec(location.hash || "");
    return m ? +m[1] : null;
  }

  /* ---------------------------------------------------------------- serve mode */

  function api(path, body) {
    // every request carries the run's token (pccl serve refuses one without it)
    var token = BOOT.token || "";
    var opts = body === undefined ? { method: "GET", headers: { "X-PCCL-Token": token } } :
      { method: "POST", headers: { "Content-Type": "application/json", "X-PCCL-Token": token },
        body: JSON.stringify(body) };
    return fetch(path, opts).then(function (r) {
      return r.json().then(function (j) {
        if (!r.ok) throw new Error(j.error || ("HTTP " + r.status));
        return j;
      });
    });
  }
  V.api = api;

  function showExplorer(x) {
    V.explorer = x;
    $("init-count").textContent = String(x.n_initial);
    $("init-index").max = Math.max(0, x.n_initial - 1);
    $("init-index").value = x.initial_index;
    $("explorer-status").textContent = "depth " + x.depth + " · " + x.successors.length + " enabled transition" +
      (x.successors.length === 1 ? "" : "s") + (x.terminal ? " · " + x.terminal : "");
    var ul = $("checks");
    ul.textContent = "";
    x.checks.forEach(function (c) {
      var li = ul.appendChild(el("li", { "data-name": c.name, "data-holds": c.holds ? "true" : "false" },
        (c.holds ? "✓ " : "✗ ") + c.name + (c.holds ? " holds" : " violated") + (c.message ? ": " + c.message : "")));
      if (!c.holds) li.classList.add("bad");
    });
    var ol = $("successors");
    ol.textContent = "";
    x.successors.forEach(function (s) {
      var li = ol.appendChild(el("li"));
      var b = li.appendChild(el("button", { "class": "succ", "data-index": s.index, "data-rule": s.rule,
        "data-agent": s.agent === null ? "" : s.agent, "data-line": s.line === null ? "" : s.line }, s.text));
      b.onclick = function () { act("/api/step", { index: s.index }); };
    });
    var sel = $("visited");
    sel.textContent = "";
    x.visited.forEach(function (v) { sel.appendChild(el("option", { value: v.id }, "#" + v.id + " depth " + v.depth + ": " + v.text)); });
    sel.value = x.current_visit;
  }

  function act(path, body) {
    $("error").textContent = "";
    return api(path, body).then(function (j) { V.receive(j); return j; })
      .catch(function (e) { $("error").textContent = e.message; throw e; });
  }
  V.act = act;
  V.receive = function (j) {
    V.pause();
    V.load(j.view);
    showExplorer(j.explorer);
    V.goto(V.trace.empty ? 0 : V.trace.n, true);
    document.body.setAttribute("data-depth", String(j.explorer.depth));
  };

  function wireExplorer() {
    $("explorer").hidden = false;
    $("back").onclick = function () { act("/api/back", {}); };
    $("here").onclick = function () { act("/api/truncate", { depth: V.k }); };
    $("init-go").onclick = function () { act("/api/init", { index: +$("init-index").value }); };
    $("visit-go").onclick = function () { act("/api/visit", { id: +$("visited").value }); };
    $("search-go").onclick = function () {
      $("search-result").textContent = "searching…";
      $("search-stop").hidden = false;
      api("/api/search", { depth: +$("search-depth").value, max_states: +$("search-states").value })
        .then(function (j) {
          $("search-stop").hidden = true;
          $("search-result").textContent = j.text;
          $("search-result").setAttribute("data-status", j.status);
          $("search-follow").hidden = !j.path_length;
        }).catch(function (e) {
          $("search-stop").hidden = true;
          $("search-result").textContent = ""; $("error").textContent = e.message;
        });
    };
    $("search-stop").onclick = function () { api("/api/search/stop", {}).catch(function () {}); };
    $("search-follow").onclick = function () { act("/api/follow", {}); };
    $("load-file").onchange = function () {
      var f = this.files[0];
      if (!f) return;
      f.text().then(function (text) { return act("/api/load", { text: text, name: f.name }); }).catch(function () {});
    };
  }

  /* ---------------------------------------------------------------- boot */

  function boot() {
    wire();
    wireWatch();
    if (BOOT.mode === "serve") {
      wireExplorer();
      api("/api/state").then(V.receive).catch(function (e) { $("error").textContent = e.message; });
      return;
    }
    var h = hashStep();
    V.load(BOOT.data);
    if (h !== null) V.goto(h);
    window.addEventListener("hashchange", function () { var s = hashStep(); if (s !== null && s !== V.k) V.goto(s); });
  }
  if (typeof document !== "undefined" && document.getElementById("controls")) boot();
})();
