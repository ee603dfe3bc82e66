// shadowbench page: one view at a time (the overview, a scene, stability) chosen by the URL's
// #fragment; a scene's plot, viewer and run table come alive the first time it is shown.
"use strict";
(() => {
  document.body.classList.add("js");
  const views = [...document.querySelectorAll("section.view")];
  const started = new Set();

  function show() {
    const id = decodeURIComponent(location.hash.slice(1)) || "overview";
    const target = document.getElementById(id);
    const view = (target && target.closest("section.view")) || views[0];
    for (const v of views) v.classList.toggle("shown", v === view);
    if (!view) return;
    if (!started.has(view)) {
      started.add(view);
      if (view.classList.contains("scene")) startScene(view);
      for (const box of view.querySelectorAll(".chart-box[id]")) staticChart(box);
    }
    if (target && target !== view) target.scrollIntoView();
    else window.scrollTo(0, 0);
  }

  function staticChart(box) {
    const script = box.parentNode.querySelector(`script.chart-spec[data-for="${box.id}"]`);
    if (!script) return;
    const spec = JSON.parse(script.textContent), hidden = new Set();
    const chart = document.createElement("div");
    box.append(document.createElement("div"), chart);
    const redraw = () => Charts.draw(chart, spec, hidden);
    if (spec.legend) Charts.legend(box.firstChild, spec.legend, hidden, redraw);
    redraw();
  }

  // --- the overview's summary tables: one per (cost, error), chosen by two selects ---------
  const summaryError = document.querySelector(".pick-summary-error");
  const summaryCost = document.querySelector(".pick-summary-cost");
  function pickSummary() {
    for (const t of document.querySelectorAll("table.summary")) {
      t.hidden = !(t.dataset.error === summaryError.value && t.dataset.cost === summaryCost.value);
    }
  }
  if (summaryError) {
    summaryError.addEventListener("change", pickSummary);
    summaryCost.addEventListener("change", pickSummary);
  }

  // --- a scene -------------------------------------------------------------------------------
  const fmt = v => (v === null || v === undefined) ? "–" : Charts.label(v);

  function tipText(run) {
    const v = run.values, lines = [`${run.technique} ${run.size}${run.setting ? "  " + run.setting : ""}`];
    let time = `time ${fmt(v.time_ms)} ms`;
    if (run.ci) time += ` (95% interval ${fmt(run.ci[0])}–${fmt(run.ci[1])})`;
    if (run.noisy) time += " noisy";
    lines.push(time);
    if (v.gpu_estimate_ms !== null) lines.push(`estimated GPU time ${fmt(v.gpu_estimate_ms)} ms`);
    const errors = ["edge_mae", "edge_ratio", "wrong_pct", "mae", "flip", "acne_pct", "leak_pct"]
      .filter(k => v[k] !== null).map(k => `${k} ${fmt(v[k])}${k.endsWith("_pct") ? " %" : ""}`);
    for (let i = 0; i < errors.length; i += 3) lines.push(errors.slice(i, i + 3).join(" · "));
    if (run.params) lines.push(run.params);
    lines.push("click: its images");
    return lines.join("\n");
  }

  function startScene(section) {
    const data = JSON.parse(section.querySelector("script.scene-data").textContent);
    const viewer = makeViewer(section, data);
    const plot = section.querySelector(".chart-box.cost-accuracy");
    if (plot && data.plot) {
      const pickError = section.querySelector(".pick-error"), pickCost = section.querySelector(".pick-cost");
      const hidden = new Set();
      const redraw = () => Charts.draw(plot, costAccuracySpec(data, pickCost.value, pickError.value,
                                                              viewer.select), hidden);
      const techniques = [...new Set(data.runs.map(r => r.technique))].sort();
      Charts.legend(section.querySelector(".legend-box"),
                    techniques.map(t => ({name: t, colour: data.colours[t]})), hidden, redraw);
      pickError.addEventListener("change", redraw);
      pickCost.addEventListener("change", redraw);
      redraw();
    }
    for (const tr of section.querySelectorAll("tr[data-run]")) {
      tr.addEventListener("click", () => viewer.select(Number(tr.dataset.run)));
    }
    const first = data.runs.find(r => r.images);
    if (first) viewer.select(first.i, false);
  }

  function costAccuracySpec(data, cost, error, onclick) {
    const view = data.plot.views[`${cost}|${error}`] || {lines: [], front: []};
    const facets = data.plot.sizes.map(size => {
      const series = view.lines.filter(l => l.size === size).map(line => ({
        name: line.name, group: line.technique, colour: data.colours[line.technique],
        points: line.runs.map((i, k) => ({x: data.runs[i].values[cost], y: data.runs[i].values[error],
                                           label: line.labels[k], tip: tipText(data.runs[i]), run: i}))
          .filter(p => p.x !== null && p.y !== null)}));
      const front = view.front.map(i => data.runs[i]).filter(r => r.size === size)
        .map(r => ({x: r.values[cost], y: r.values[error]}));
      return {title: size, series, front};
    });
    return {facets, onclick, x: {title: data.plot.costs[cost], log: true},
            y: {title: data.plot.errors[error], log: true}};
  }

  // --- the image viewer -------------------------------------------------------------------
  function makeViewer(section, data) {
    const box = section.querySelector(".viewer");
    const slot = name => box.querySelector(`figure[data-slot="${name}"]`);
    const under = box.querySelector(".compare-stack .under"), over = box.querySelector(".compare-stack .over");
    const slider = box.querySelector(".compare-slider");
    let flicker = null;
    const wipe = () => { over.style.clipPath = `inset(0 ${100 - slider.value}% 0 0)`; };
    slider.addEventListener("input", wipe);
    box.querySelector(".flicker").addEventListener("click", e => {
      if (flicker) { clearInterval(flicker); flicker = null; over.style.opacity = 1; e.target.textContent = "flicker"; return; }
      over.style.clipPath = "none";
      flicker = setInterval(() => { over.style.opacity = over.style.opacity === "0" ? 1 : 0; }, 450);
      e.target.textContent = "stop flicker";
    });

    function put(name, uri, native, caption, size) {
      const fig = slot(name);
      fig.hidden = !uri;
      if (!uri) return;
      const img = fig.querySelector("img");
      img.src = uri;
      img.onclick = () => openNative(native || uri, uri, caption, size);
    }

    function select(i, scroll = true) {
      const run = data.runs[i];
      for (const tr of section.querySelectorAll("tr[data-run]")) tr.classList.toggle("selected", Number(tr.dataset.run) === i);
      const title = `${run.technique} ${run.size}${run.setting ? " · " + run.setting : ""}`;
      box.querySelector(".viewer-title").textContent = title + (run.images ? ` — edge_mae ${fmt(run.values.edge_mae)}, wrong_pct ${fmt(run.values.wrong_pct)} %, time ${fmt(run.values.time_ms)} ms` : "");
      const ref = data.references[run.size];
      const note = box.querySelector(".viewer-note");
      note.textContent = run.images ? "" : `No images for this run: ${run.unavailable}`;
      const img = run.images || {native: {}, maps: []};
      put("ref", ref && ref.ref, ref && ref.native.ref, `reference ${run.size}`, run.size);
      put("v", img.v, img.native.v, `${title}: V`, run.size);
      put("err", img.err, img.native.err, `${title}: error V − V_ref`, run.size);
      put("shaded_ref", img.shaded && ref && ref.shaded, ref && ref.native.shaded, `shaded reference ${run.size}`, run.size);
      put("shaded", img.shaded, img.native.shaded, `${title}: shaded`, run.size);
      under.src = (ref && ref.ref) || ""; over.src = img.v || "";
      under.onclick = over.onclick = () => openNative(img.native.v || img.v, img.v, `${title}: V`, run.size);
      wipe();
      const crops = box.querySelector(".viewer-crops");
      crops.hidden = !img.crop;
      if (img.crop) {
        const [r, c, s] = img.crop.at;
        crops.querySelector(".crop-title").textContent =
          `The window of the largest edge error: rows ${r}–${r + s}, columns ${c}–${c + s} of ${run.size}, at native pixels enlarged`;
        for (const k of ["ref", "v", "err"]) {
          const im = slot("crop_" + k).querySelector("img");
          im.src = img.crop[k];
          im.onclick = () => openNative(img.crop[k], img.crop[k], `${title}: ${k} crop`, `${s}x${s}`);
        }
      }
      const maps = box.querySelector(".viewer-maps");
      maps.textContent = "";
      for (const m of img.maps) {
        const fig = document.createElement("figure"), im = document.createElement("img"), cap = document.createElement("figcaption");
        im.src = m.uri; im.alt = m.name;
        cap.textContent = `${m.name}: ${fmt(m.lo)} (dark) to ${fmt(m.hi)} (yellow); grey: none`;
        fig.append(im, cap);
        maps.appendChild(fig);
      }
      if (scroll) box.scrollIntoView({block: "nearest"});
    }
    return {select};
  }

  // --- native size ----------------------------------------------------------------------------
  const overlay = document.getElementById("overlay");
  const big = overlay.querySelector("img");
  let zoom = 1;
  const fit = () => { if (big.naturalWidth) big.style.width = `${big.naturalWidth * zoom}px`; };
  big.addEventListener("load", fit);
  for (const b of overlay.querySelectorAll("button[data-zoom]")) {
    b.addEventListener("click", () => { zoom = Number(b.dataset.zoom); fit(); });
  }
  const close = () => { overlay.hidden = true; big.removeAttribute("src"); };
  overlay.querySelector(".overlay-close").addEventListener("click", close);
  document.addEventListener("keydown", e => { if (e.key === "Escape") close(); });

  function openNative(src, fallback, caption, size) {
    zoom = 1;
    overlay.querySelector(".overlay-caption").textContent = `${caption} (${size})`;
    const note = overlay.querySelector(".overlay-note");
    note.textContent = "";
    big.onerror = () => {
      big.onerror = null;
      note.textContent = `The native-size file ${src} is not beside this page (it lives in the results folder's images/); showing the embedded, reduced image.`;
      big.src = fallback;
    };
    big.src = src;
    overlay.hidden = false;
  }

  if (views.length) {
    window.addEventListener("hashchange", show);
    show();
  } else {
    for (const box of document.querySelectorAll(".chart-box[id]")) staticChart(box);
  }
})();
