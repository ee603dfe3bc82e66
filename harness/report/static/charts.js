// shadowbench charts: small multiples of points and lines in SVG, no dependency. A chart fills
// its container's width and is drawn again when that width changes; ticks are chosen for any
// data (log or linear, one value to many decades) with exact, distinct labels; point labels,
// tick labels and titles go through one collision pass, first free spot wins, so no two
// overlap: a label with no free spot is left out and its point's hover still says it.
"use strict";
const Charts = (() => {
  const NS = "http://www.w3.org/2000/svg";
  // A panel is at least MIN_PANEL px wide (fewer panels per row otherwise); its height follows
  // its width within [MIN_HEIGHT, MAX_HEIGHT].
  const MIN_PANEL = 680, GAP = 12, MIN_HEIGHT = 280, MAX_HEIGHT = 500, ASPECT = 0.42;
  const MARGIN = {right: 24, top: 24, bottom: 42};
  const TICK_PX = {x: 90, y: 42};  // room per tick label along each axis
  const LOG_MIN_DECADES = 0.7;  // a log axis spans at least this (one value: 5×10⁴ 10⁵ 2×10⁵)

  function el(tag, attrs, parent) {
    const node = document.createElementNS(NS, tag);
    for (const [k, v] of Object.entries(attrs || {})) node.setAttribute(k, v);
    if (parent) parent.appendChild(node);
    return node;
  }

  // A value for tables and hovers: 0.02, 20, 1000, 3 significant digits.
  function label(v) {
    if (v === 0) return "0";
    const a = Math.abs(v);
    if (a >= 1e5 || a < 1e-4) return v.toExponential(0);
    return String(Number(v.toPrecision(3)));
  }

  // --- ticks --------------------------------------------------------------------------------
  const SUPER = {"-": "⁻", "0": "⁰", "1": "¹", "2": "²", "3": "³", "4": "⁴", "5": "⁵", "6": "⁶",
                 "7": "⁷", "8": "⁸", "9": "⁹"};
  const round12 = v => Number(v.toPrecision(12)) + 0;  // + 0: no -0

  // An axis's tick labels, each exact (the fewest digits that give the tick back), so distinct
  // ticks never share a label; in powers of ten on an axis that reaches 10⁵ or below 10⁻⁴:
  // 0.25, 1500; 5×10⁴, 10⁵, 2×10⁵.
  function tickLabels(ticks) {
    const powers = ticks.some(v => Math.abs(v) >= 1e5 || (v !== 0 && Math.abs(v) < 1e-4));
    return ticks.map(v => {
      if (v === 0) return "0";
      let p = 1;
      while (p < 15 && Math.abs(Number(v.toPrecision(p)) - v) > Math.abs(v) * 1e-10) p++;
      if (!powers) return String(Number(v.toPrecision(p)));
      const [m, e] = v.toExponential(p - 1).split("e");
      const power = "10" + String(Number(e)).replace(/./g, c => SUPER[c]);
      return m === "1" ? power : m === "-1" ? "-" + power : `${m}×${power}`;
    });
  }

  function linearTicks(lo, hi, most) {
    const span = hi - lo;
    const mag = 10 ** Math.floor(Math.log10(span / Math.max(most, 1)));
    const steps = [1, 2, 2.5, 5, 10, 20, 25, 50, 100].map(m => m * mag);
    const make = step => {
      const out = [];
      for (let k = Math.ceil(lo / step - 1e-9); k * step <= hi + step * 1e-9; k++) out.push(round12(k * step));
      return out;
    };
    let previous = null;
    for (const step of steps) {
      const ticks = make(step);
      if (ticks.length <= most) return ticks.length >= 2 || !previous ? ticks : previous;
      previous = ticks;
    }
    return previous;
  }

  function logTicks(lo, hi, most) {
    const e0 = Math.floor(Math.log10(lo)), e1 = Math.ceil(Math.log10(hi));
    const make = (mantissas, every = 1) => {
      const out = [];
      for (let e = e0; e <= e1; e++) {
        if (((e % every) + every) % every) continue;
        for (const m of mantissas) {
          const v = round12(m * 10 ** e);
          if (v >= lo * (1 - 1e-12) && v <= hi * (1 + 1e-12)) out.push(v);
        }
      }
      return out;
    };
    const ordinary = [make([1, 2, 5]), make([1, 3]), make([1])];
    for (const every of [2, 3, 5, 10, 20, 50, 100]) ordinary.push(make([1], every));
    let ticks = ordinary.find(t => t.length <= most) || ordinary[ordinary.length - 1];
    if (ticks.length < 3) {  // less than a decade or two: the densest of these that fits
      const denser = [[1, 2, 3, 4, 5, 6, 7, 8, 9], [1, 2, 3, 4, 5, 7], [1, 2, 3, 5]].map(m => make(m))
        .find(t => t.length <= most && t.length > ticks.length);
      if (denser) ticks = denser;
    }
    return ticks.length >= 2 ? ticks : linearTicks(lo, hi, most);  // within a factor < 1.25
  }

  // The axis over ``values``: its range (holding every value, padded), at most ``most`` ticks
  // inside it with their labels, and at(v) in [0, 1].
  function axis(values, log, most = 8) {
    let lo = Math.min(...values), hi = Math.max(...values);
    most = Math.max(2, most);
    if (log) {
      const mid = (Math.log10(lo) + Math.log10(hi)) / 2;
      const half = Math.max((Math.log10(hi) - Math.log10(lo)) * 0.56, LOG_MIN_DECADES / 2);
      const a = mid - half, b = mid + half;  // 6 % of the span each side, or more
      lo = 10 ** a; hi = 10 ** b;
      const ticks = logTicks(lo, hi, most);
      return {lo, hi, log, ticks, labels: tickLabels(ticks), at: v => (Math.log10(v) - a) / (b - a)};
    }
    if (hi === lo) {
      const pad = Math.abs(hi) * 0.1 || 1;
      lo -= pad; hi += pad;
    } else {
      const pad = (hi - lo) * 0.06;
      lo = lo >= 0 && lo - pad < 0 ? 0 : lo - pad; hi += pad;
    }
    const ticks = linearTicks(lo, hi, most), l = lo, h = hi;
    return {lo, hi, log, ticks, labels: tickLabels(ticks), at: v => (v - l) / (h - l)};
  }

  // --- collision pass -------------------------------------------------------------------------
  // Boxes are [left, top, right, bottom]; a label takes the first free candidate box.
  const overlaps = (a, b) => a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3];
  const within = (a, b) => a[0] >= b[0] && a[1] >= b[1] && a[2] <= b[2] && a[3] <= b[3];

  function makeSpace(bounds) {
    const taken = [];
    return {
      taken,
      free: box => within(box, bounds) && !taken.some(t => overlaps(t, box)),
      take: box => { taken.push(box); },
    };
  }

  // Each text's box relative to its anchor, measured once in the page (one layout for all).
  function measure(texts) {
    return texts.map(t => {
      const b = t.getBBox();
      return {x: b.x - Number(t.getAttribute("x") || 0), y: b.y - Number(t.getAttribute("y") || 0),
              w: b.width, h: b.height};
    });
  }

  // Put ``text`` at the first anchor of ``anchors`` where its box (``m``, padded) is free;
  // remove it when none is. Returns whether it stayed.
  const boxAt = ([x, y], m, pad) => [x + m.x - pad, y + m.y - pad, x + m.x + m.w + pad, y + m.y + m.h + pad];
  const anchorOf = text => [Number(text.getAttribute("x")), Number(text.getAttribute("y"))];

  function place(text, m, anchors, space, pad = 1) {
    for (const [x, y] of anchors) {
      const box = boxAt([x, y], m, pad);
      if (space.free(box)) {
        text.setAttribute("x", x); text.setAttribute("y", y);
        space.take(box);
        return true;
      }
    }
    text.remove();
    return false;
  }

  // Anchors (for text-anchor start) around a point of radius r for a label of size m: upper
  // right first (where labels always went), then right, lower right, the left side, above, below.
  function around(px, py, r, m) {
    const d = r + 3, dx = d * 0.8, left = v => v - m.w, top = v => v - (m.y + m.h), mid = py - m.y - m.h / 2;
    const bottom = v => v - m.y;
    return [[px + dx, top(py - dx)], [px + d, mid], [px + dx, bottom(py + dx)],
            [left(px - dx), top(py - dx)], [left(px - d), mid], [left(px - dx), bottom(py + dx)],
            [px - m.w / 2, top(py - d)], [px - m.w / 2, bottom(py + d)]];
  }

  // --- drawing --------------------------------------------------------------------------------
  const state = new WeakMap();
  const observer = typeof ResizeObserver === "undefined" ? null : new ResizeObserver(entries => {
    for (const e of entries) {
      const s = state.get(e.target);
      if (s && Math.abs(e.target.clientWidth - s.width) > 1) render(e.target, s);
    }
  });

  // spec: {facets: [{title, series: [{name, group, colour, dash, markers, points: [{x, y,
  //        label, tip, run, r (radius, default 4.5)}]}], front: [{x, y}]}], x: {title, log},
  //        y: {title, log, shared},
  //        onclick(run)}; hidden: a Set of series groups not drawn. The panels share both
  //        axes unless y.shared is false. Drawn again (labels placed again) when the
  //        container's width changes.
  function draw(parent, spec, hidden) {
    const s = {spec, hidden: hidden || new Set(), width: -1};
    state.set(parent, s);
    if (observer) observer.observe(parent);
    render(parent, s);
  }

  function render(parent, s) {
    const {spec, hidden} = s;
    s.width = parent.clientWidth;
    parent.style.minHeight = `${parent.offsetHeight}px`;  // the page keeps its height meanwhile
    parent.textContent = "";
    const shown = f => f.series.filter(x => !hidden.has(x.group || x.name));
    const xs = [], ys = [];
    for (const f of spec.facets) {
      for (const x of shown(f)) for (const p of x.points) { xs.push(p.x); ys.push(p.y); }
    }
    const logX = spec.x.log && xs.every(v => v > 0), logY = spec.y.log && ys.every(v => v > 0);
    const title = document.createElement("div");
    title.className = "chart-y-title";
    title.textContent = "↑ " + spec.y.title + (logY ? " (log scale)" : "");
    parent.appendChild(title);
    if (!xs.length) {
      const none = document.createElement("p");
      none.textContent = "No run has both values.";
      parent.appendChild(none);
    }
    if (!xs.length || !s.width) { parent.style.minHeight = ""; return; }
    const tip = document.createElement("div");
    tip.className = "chart-tip";
    const row = document.createElement("div");
    row.className = "chart-facets";
    parent.appendChild(row);
    const n = spec.facets.length;
    const columns = Math.max(1, Math.min(n, Math.floor((s.width + GAP) / (MIN_PANEL + GAP))));
    const w = Math.floor((s.width - GAP * (columns - 1)) / columns);
    const h = Math.round(Math.min(MAX_HEIGHT, Math.max(MIN_HEIGHT, w * ASPECT)));
    const ih = h - MARGIN.top - MARGIN.bottom;
    let ay = axis(ys, logY, Math.floor(ih / TICK_PX.y));
    const yAxes = spec.facets.map(f => {
      if (spec.y.shared !== false) return ay;
      const own = shown(f).flatMap(x => x.points.map(p => p.y));
      return own.length ? axis(own, logY, Math.floor(ih / TICK_PX.y)) : ay;
    });
    const longest = Math.max(...yAxes.flatMap(a => a.labels.map(l => l.length)));
    const left = Math.max(40, 12 + 7 * longest);
    const iw = w - left - MARGIN.right;
    const ax = axis(xs, logX, Math.floor(iw / TICK_PX.x));
    spec.facets.forEach((facet, i) => {
      ay = yAxes[i];
      panel(row, facet, shown(facet), {w, h, left, iw, ih, ax, ay, logX, spec, tip, parent});
    });
    parent.appendChild(tip);
    parent.style.minHeight = "";
  }

  function panel(row, facet, series, c) {
    const {w, h, left, iw, ih, ax, ay} = c, top = MARGIN.top;
    const px = x => left + ax.at(x) * iw, py = y => top + (1 - ay.at(y)) * ih;
    const svg = el("svg", {width: w, height: h, class: "chart", viewBox: `0 0 ${w} ${h}`}, row);
    const space = makeSpace([0, 0, w, h]);
    // titles first: they always stay
    const titles = [el("text", {x: left + iw / 2, y: 15, "text-anchor": "middle", class: "facet-title"}, svg),
                    el("text", {x: left + iw / 2, y: h - 6, "text-anchor": "middle", class: "axis-title"}, svg)];
    titles[0].textContent = facet.title;
    titles[1].textContent = c.spec.x.title + (c.logX ? " (log)" : "");
    const grid = el("g", {class: "grid"}, svg);
    const ticks = [];
    ax.ticks.forEach((t, i) => {
      el("line", {x1: px(t), x2: px(t), y1: top, y2: top + ih}, grid);
      ticks.push({node: el("text", {x: px(t), y: top + ih + 15, "text-anchor": "middle"}, grid), text: ax.labels[i]});
    });
    ay.ticks.forEach((t, i) => {
      el("line", {x1: left, x2: left + iw, y1: py(t), y2: py(t)}, grid);
      ticks.push({node: el("text", {x: left - 5, y: py(t) + 4, "text-anchor": "end"}, grid), text: ay.labels[i]});
    });
    for (const t of ticks) t.node.textContent = t.text;
    el("rect", {x: left, y: top, width: iw, height: ih, class: "frame"}, svg);
    if (facet.front && facet.front.length > 1) {
      const pts = facet.front.slice().sort((a, b) => a.x - b.x);
      let d = `M${px(pts[0].x)},${py(pts[0].y)}`;
      for (const p of pts.slice(1)) d += `H${px(p.x)}V${py(p.y)}`;
      el("path", {d, class: "front"}, svg);
    }
    const onFront = new Set((facet.front || []).map(p => `${p.x}|${p.y}`));
    const labels = [], points = [];
    for (const s of series) {
      const g = el("g", {class: "series"}, svg);
      if (s.points.length > 1) {
        el("polyline", {points: s.points.map(p => `${px(p.x)},${py(p.y)}`).join(" "),
                        stroke: s.colour, "stroke-dasharray": s.dash ? "5,4" : "none",
                        class: "line"}, g);
      }
      for (const p of s.points) {
        const r = s.markers !== false ? (p.r || 4.5) : 0;
        points.push([px(p.x), py(p.y), r]);
        if (r) dot(g, p, px(p.x), py(p.y), r, s.colour, c);
        if (p.label) {
          const node = el("text", {x: 0, y: 0, fill: s.colour, class: "point-label"}, g);
          node.textContent = p.label;
          labels.push({node, x: px(p.x), y: py(p.y), r, front: onFront.has(`${p.x}|${p.y}`)});
        }
      }
    }
    // one measuring layout for every text of the panel, then the collision pass
    const sizes = measure([...titles, ...ticks.map(t => t.node), ...labels.map(l => l.node)]);
    titles.forEach((t, i) => space.take(boxAt(anchorOf(t), sizes[i], 0)));  // titles always stay
    ticks.forEach((t, i) => place(t.node, sizes[2 + i], [anchorOf(t.node)], space, 2));
    const plot = makeSpace([left, top, left + iw, top + ih]);
    for (const [x, y, r] of points) if (r) plot.take([x - r, y - r, x + r, y + r]);
    const order = labels.map((l, i) => i).sort((a, b) => labels[b].front - labels[a].front);
    for (const i of order) {
      const l = labels[i], m = sizes[2 + ticks.length + i];
      place(l.node, m, around(l.x, l.y, l.r, m), plot);
    }
  }

  function dot(g, p, x, y, r, colour, c) {
    const node = el("circle", {cx: x, cy: y, r, fill: colour,
                               class: "point" + (p.run !== undefined ? " link" : "")}, g);
    node.addEventListener("mousemove", e => {
      c.tip.textContent = p.tip;
      c.tip.style.display = "block";
      const box = c.parent.getBoundingClientRect();
      c.tip.style.left = `${e.clientX - box.left + 14}px`;
      c.tip.style.top = `${e.clientY - box.top + 10}px`;
    });
    node.addEventListener("mouseleave", () => { c.tip.style.display = "none"; });
    if (p.run !== undefined && c.spec.onclick) node.addEventListener("click", () => c.spec.onclick(p.run));
  }

  // A legend of groups that hides and shows them; redraw() draws again with the hidden set
  // (and so places the labels again). Its chips wrap in a row: they never overlap.
  function legend(parent, entries, hidden, redraw) {
    parent.textContent = "";
    for (const {name, colour} of entries) {
      const item = document.createElement("button");
      item.type = "button";
      item.className = "legend-item" + (hidden.has(name) ? " off" : "");
      const swatch = document.createElement("span");
      swatch.className = "swatch";
      swatch.style.background = colour;
      item.append(swatch, name);
      item.title = "show or hide " + name;
      item.addEventListener("click", () => {
        hidden.has(name) ? hidden.delete(name) : hidden.add(name);
        item.classList.toggle("off");
        redraw();
      });
      parent.appendChild(item);
    }
  }

  return {draw, legend, label, axis};
})();
