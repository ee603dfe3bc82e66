// shadowbench charts: small multiples of points and lines in SVG, log or linear axes with
// plain 1-2-5 tick labels, a hover box and click-through. No dependency.
"use strict";
const Charts = (() => {
  const NS = "http://www.w3.org/2000/svg";
  const SIZE = {width: 400, height: 300, left: 58, right: 12, top: 22, bottom: 34};

  function el(tag, attrs, parent) {
    const node = document.createElementNS(NS, tag);
    for (const [k, v] of Object.entries(attrs || {})) node.setAttribute(k, v);
    if (parent) parent.appendChild(node);
    return node;
  }

  // Plain labels: 0.02, 20, 1000; never "2" standing for 20.
  function label(v) {
    if (v === 0) return "0";
    const a = Math.abs(v);
    if (a >= 1e5 || a < 1e-4) return v.toExponential(0);
    return String(Number(v.toPrecision(3)));
  }

  function linearTicks(lo, hi) {
    const span = hi - lo || Math.abs(hi) || 1;
    const raw = span / 5, mag = 10 ** Math.floor(Math.log10(raw));
    const step = [1, 2, 5, 10].map(m => m * mag).find(s => span / s <= 6);
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) {
      out.push(Number(v.toPrecision(12)));
    }
    return out;
  }

  function logTicks(lo, hi) {
    for (const mantissas of [[1, 2, 5], [1, 3], [1]]) {
      const out = [];
      for (let e = Math.floor(Math.log10(lo)); e <= Math.ceil(Math.log10(hi)); e++) {
        for (const m of mantissas) {
          const v = Number((m * 10 ** e).toPrecision(12));
          if (v >= lo * (1 - 1e-9) && v <= hi * (1 + 1e-9)) out.push(v);
        }
      }
      if (out.length <= 9) return out.length >= 2 ? out : linearTicks(lo, hi).filter(v => v > 0);
    }
    return [];
  }

  function axis(values, log) {
    let lo = Math.min(...values), hi = Math.max(...values);
    if (log) {
      const pad = (Math.log10(hi) - Math.log10(lo)) * 0.06 || 0.1;
      lo = 10 ** (Math.log10(lo) - pad); hi = 10 ** (Math.log10(hi) + pad);
      const a = Math.log10(lo), b = Math.log10(hi);
      return {ticks: logTicks(lo, hi), at: t => (Math.log10(t) - a) / (b - a)};
    }
    const pad = (hi - lo) * 0.06 || Math.abs(hi) * 0.1 || 1;
    lo = lo >= 0 && lo - pad < 0 ? 0 : lo - pad; hi += pad;
    return {ticks: linearTicks(lo, hi), at: t => (t - lo) / (hi - lo)};
  }

  // spec: {facets: [{title, series: [{name, group, colour, dash, markers, points: [{x, y,
  //        label, tip, run}]}], front: [{x, y}]}], x: {title, log}, y: {title, log, shared},
  //        onclick(run)}; hidden: a Set of series groups not drawn. The panels share both
  //        axes unless y.shared is false.
  function draw(parent, spec, hidden) {
    parent.textContent = "";
    hidden = hidden || new Set();
    const shown = f => f.series.filter(s => !hidden.has(s.group || s.name));
    const xs = [], ys = [];
    for (const f of spec.facets) {
      for (const s of shown(f)) for (const p of s.points) { xs.push(p.x); ys.push(p.y); }
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
      return;
    }
    const ax = axis(xs, logX);
    let ay = axis(ys, logY);
    const tip = document.createElement("div");
    tip.className = "chart-tip";
    const row = document.createElement("div");
    row.className = "chart-facets";
    parent.appendChild(row);
    const w = Math.max(260, Math.min(SIZE.width, (parent.clientWidth || 1200) / spec.facets.length - 8));
    const iw = w - SIZE.left - SIZE.right, ih = SIZE.height - SIZE.top - SIZE.bottom;
    const px = x => SIZE.left + ax.at(x) * iw, py = y => SIZE.top + (1 - ay.at(y)) * ih;
    for (const facet of spec.facets) {
      if (spec.y.shared === false) {  // each panel its own metric: its own y range
        const own = shown(facet).flatMap(s => s.points.map(p => p.y));
        if (own.length) ay = axis(own, logY);
      }
      const svg = el("svg", {width: w, height: SIZE.height, class: "chart",
                             viewBox: `0 0 ${w} ${SIZE.height}`}, row);
      el("text", {x: SIZE.left + iw / 2, y: 14, "text-anchor": "middle", class: "facet-title"},
         svg).textContent = facet.title;
      const grid = el("g", {class: "grid"}, svg);
      for (const t of ax.ticks) {
        el("line", {x1: px(t), x2: px(t), y1: SIZE.top, y2: SIZE.top + ih}, grid);
        el("text", {x: px(t), y: SIZE.top + ih + 14, "text-anchor": "middle"}, grid).textContent = label(t);
      }
      for (const t of ay.ticks) {
        el("line", {x1: SIZE.left, x2: SIZE.left + iw, y1: py(t), y2: py(t)}, grid);
        el("text", {x: SIZE.left - 4, y: py(t) + 4, "text-anchor": "end"}, grid).textContent = label(t);
      }
      el("rect", {x: SIZE.left, y: SIZE.top, width: iw, height: ih, class: "frame"}, svg);
      el("text", {x: SIZE.left + iw / 2, y: SIZE.height - 4, "text-anchor": "middle",
                  class: "axis-title"}, svg).textContent = spec.x.title + (logX ? " (log)" : "");
      if (facet.front && facet.front.length > 1) {
        const pts = facet.front.slice().sort((a, b) => a.x - b.x);
        let d = `M${px(pts[0].x)},${py(pts[0].y)}`;
        for (const p of pts.slice(1)) d += `H${px(p.x)}V${py(p.y)}`;
        el("path", {d, class: "front"}, svg);
      }
      for (const s of shown(facet)) {
        const g = el("g", {class: "series"}, svg);
        if (s.points.length > 1) {
          el("polyline", {points: s.points.map(p => `${px(p.x)},${py(p.y)}`).join(" "),
                          stroke: s.colour, "stroke-dasharray": s.dash ? "5,4" : "none",
                          class: "line"}, g);
        }
        for (const p of s.points) {
          if (s.markers !== false) {
            const dot = el("circle", {cx: px(p.x), cy: py(p.y), r: 4.5, fill: s.colour,
                                      class: "point" + (p.run !== undefined ? " link" : "")}, g);
            dot.addEventListener("mousemove", e => {
              tip.textContent = p.tip;
              tip.style.display = "block";
              const box = parent.getBoundingClientRect();
              tip.style.left = `${e.clientX - box.left + 14}px`;
              tip.style.top = `${e.clientY - box.top + 10}px`;
            });
            dot.addEventListener("mouseleave", () => { tip.style.display = "none"; });
            if (p.run !== undefined && spec.onclick) {
              dot.addEventListener("click", () => spec.onclick(p.run));
            }
          }
          if (p.label) {
            el("text", {x: px(p.x) + 6, y: py(p.y) - 6, fill: s.colour, class: "point-label"},
               g).textContent = p.label;
          }
        }
      }
    }
    parent.appendChild(tip);
  }

  // A legend of groups that hides and shows them; redraw() draws again with the hidden set.
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

  return {draw, legend, label, logTicks};
})();
