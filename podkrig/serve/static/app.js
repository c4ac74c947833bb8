// podkrig serve: the page. Plain JavaScript, no build step; charts by the vendored uPlot.
// Every request goes to the server that served this page (relative URLs only).
// The HTTP contract is described in docs/serve.md.
"use strict";

(() => {
  // ---------------------------------------------------------------- helpers
  const $ = (sel, root = document) => root.querySelector(sel);
  const $$ = (sel, root = document) => Array.from(root.querySelectorAll(sel));

  function h(tag, attrs, ...children) {
    const node = document.createElement(tag);
    for (const [key, value] of Object.entries(attrs || {})) {
      if (value === null || value === undefined || value === false) continue;
      if (key === "class") node.className = value;
      else if (key === "text") node.textContent = value;
      else if (key.startsWith("on")) node.addEventListener(key.slice(2), value);
      else node.setAttribute(key, value === true ? "" : value);
    }
    for (const child of children.flat()) {
      if (child === null || child === undefined || child === false) continue;
      node.append(child instanceof Node ? child : document.createTextNode(String(child)));
    }
    return node;
  }

  const SVG_NS = "http://www.w3.org/2000/svg";
  function s(tag, attrs) {
    const node = document.createElementNS(SVG_NS, tag);
    for (const [key, value] of Object.entries(attrs || {})) node.setAttribute(key, value);
    return node;
  }

  // A number with 4 significant digits; a dimensionless unit ("-") is written [-].
  function num(value, digits = 4) {
    if (value === null || value === undefined || Number.isNaN(value)) return "–";
    if (!Number.isFinite(value)) return String(value);
    const a = Math.abs(value);
    if (a !== 0 && (a >= 1e6 || a < 1e-3)) return value.toExponential(digits - 1);
    return Number(value.toPrecision(digits)).toString();
  }
  const unitText = (unit) => (!unit || unit === "-" ? "[-]" : unit);
  const bracketUnit = (unit) => (!unit || unit === "-" ? "[-]" : `[${unit}]`);
  const withUnit = (value, unit, digits) => `${num(value, digits)} ${unitText(unit)}`;
  const testLabel = (test, i) => (test.name === null || test.name === undefined || test.name === ""
    ? `test ${i + 1}: ${test.scenario}` : `${test.name} (${test.scenario})`);

  class ApiError extends Error {
    constructor(message, field, status) {
      super(message);
      this.field = field;
      this.status = status;
    }
  }

  async function api(method, path, body) {
    const options = { method, headers: { Accept: "application/json" } };
    if (body !== undefined) {
      options.headers["Content-Type"] = "application/json";
      options.body = JSON.stringify(body);
    }
    let response;
    try {
      response = await fetch(path, options);
    } catch (err) {
      throw new ApiError(`the podkrig server does not answer (${err.message}); is \`podkrig serve\` still running?`, null, 0);
    }
    const text = await response.text();
    let data = null;
    try {
      data = text ? JSON.parse(text) : null;
    } catch (err) {
      data = { error: text };
    }
    if (!response.ok) {
      throw new ApiError((data && data.error) || `${response.status} ${response.statusText}`,
        (data && data.field) || null, response.status);
    }
    return data;
  }

  const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
  const PALETTE = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf",
    "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22"];
  const color = (i) => PALETTE[i % PALETTE.length];
  function rgba(hex, alpha) {
    const v = parseInt(hex.slice(1), 16);
    return `rgba(${(v >> 16) & 255},${(v >> 8) & 255},${v & 255},${alpha})`;
  }

  // Show an API error next to the input it names (#err-FIELD, or the last dotted part of FIELD),
  // else in the screen's general error box.
  function showError(err, fallback) {
    const field = err.field;
    if (field) {
      const parts = String(field).split(".");
      const candidates = [field, parts[parts.length - 1]];
      if (parts[0] === "noise") {
        // "noise.TEST.noise_rel", or "noise.noise_rel" for a study of one test
        const key = parts.length > 2 ? parts.slice(1, -1).join(".") : "";
        const input = $$("#noise-fields input").find((i) => i.dataset.noiseKey === key && i.id.endsWith(parts[parts.length - 1]));
        if (input) candidates.unshift(input.id);
      }
      for (const name of candidates) {
        const box = document.getElementById(`err-${name}`);
        if (box) {
          box.textContent = err.message;
          return;
        }
      }
    }
    fallback.textContent = field ? `${field}: ${err.message}` : err.message;
  }
  function clearErrors(root) {
    $$(".error", root).forEach((box) => { box.textContent = ""; });
  }

  // ---------------------------------------------------------------- state
  const state = {
    study: null,
    params: [],          // [{name, unit, lower, upper, scale, value, best, interval}]
    values: {},          // name -> current physical value
    locked: new Set(),
    tests: [],           // /api/study tests
    plots: [],           // per test: {readings: [{unit, plot, sensors}], resid: uPlot}
    shownRun: null,      // id of the run whose result is on the Calibrate screen
    job: null,
  };
  window.podkrigLatency = [];   // ms per slider input, input event -> plot redraw finished
  window.podkrigPredictions = 0;
  window.podkrigCalibration = [];  // ms per calibration from the page, click -> results drawn

  // ---------------------------------------------------------------- tabs
  const SCREENS = ["explore", "calibrate", "model", "jobs"];
  function showScreen(name) {
    if (!SCREENS.includes(name)) name = "explore";
    for (const screen of SCREENS) {
      $(`#screen-${screen}`).hidden = screen !== name;
      $(`#tab-${screen}`).setAttribute("aria-selected", String(screen === name));
    }
    if (location.hash !== `#/${name}`) history.replaceState(null, "", `#/${name}`);
    if (name === "explore") resizePlots();
    if (name === "calibrate") renderFrozen();
    if (name === "model" && state.fe && state.fe.curvePlot) resizeCurve();
  }
  for (const screen of SCREENS) {
    $(`#tab-${screen}`).addEventListener("click", () => showScreen(screen));
  }
  window.addEventListener("hashchange", () => showScreen(location.hash.replace(/^#\/?/, "")));

  // ---------------------------------------------------------------- explore: sliders
  const SLIDER_STEPS = 1000;
  function toSlider(p, value) {
    const lo = p.scale === "log" ? Math.log(p.lower) : p.lower;
    const hi = p.scale === "log" ? Math.log(p.upper) : p.upper;
    const v = p.scale === "log" ? Math.log(Math.max(value, p.lower * 1e-300)) : value;
    return Math.round(Math.min(1, Math.max(0, (v - lo) / (hi - lo))) * SLIDER_STEPS);
  }
  function fromSlider(p, position) {
    const t = position / SLIDER_STEPS;
    if (p.scale === "log") return Math.exp(Math.log(p.lower) + t * (Math.log(p.upper) - Math.log(p.lower)));
    return p.lower + t * (p.upper - p.lower);
  }

  function buildSliders() {
    const box = $("#sliders");
    box.replaceChildren();
    for (const p of state.params) {
      const slider = h("input", {
        type: "range", id: `param-${p.name}`, min: 0, max: SLIDER_STEPS, step: 1,
        value: toSlider(p, state.values[p.name]), "aria-label": `${p.name} ${bracketUnit(p.unit)}`,
      });
      const box2 = h("input", {
        type: "number", id: `value-${p.name}`, step: "any", value: num(state.values[p.name], 5),
        "aria-label": `${p.name} value`, title: `${p.name} in ${unitText(p.unit)}`,
      });
      const lock = h("input", { type: "checkbox", id: `lock-${p.name}` });
      const row = h("div", { class: "param", "data-param": p.name },
        h("div", { class: "head" },
          h("span", { class: "name", text: p.name }),
          box2, h("span", { class: "small", text: unitText(p.unit) }),
          h("label", { class: "lock", title: "freeze at this value for the calibration" }, lock, " lock")),
        slider,
        h("div", { class: "bounds small muted" },
          h("span", { text: withUnit(p.lower, p.unit) }),
          h("span", { text: p.scale === "log" ? "log scale" : "linear" }),
          h("span", { text: withUnit(p.upper, p.unit) })),
        h("div", { class: "error", id: `err-${p.name}`, role: "alert" }));
      slider.addEventListener("input", (event) => {
        state.values[p.name] = fromSlider(p, Number(slider.value));
        box2.value = num(state.values[p.name], 5);
        requestPrediction(event.timeStamp);
      });
      box2.addEventListener("change", (event) => {
        const value = Number(box2.value);
        if (box2.value.trim() === "" || !Number.isFinite(value)) {
          $(`#err-${p.name}`).textContent = `${p.name} needs a number in ${unitText(p.unit)}`;
          return;
        }
        state.values[p.name] = value;
        slider.value = toSlider(p, value);
        requestPrediction(event.timeStamp);
      });
      lock.addEventListener("change", () => {
        if (lock.checked) state.locked.add(p.name);
        else state.locked.delete(p.name);
        slider.disabled = lock.checked;
        box2.disabled = lock.checked;
        row.classList.toggle("locked", lock.checked);
        renderFrozen();
      });
      box.append(row);
    }
  }

  $("#reset-best").addEventListener("click", (event) => {
    for (const p of state.params) {
      if (state.locked.has(p.name)) continue;
      state.values[p.name] = p.best ?? p.value;
      $(`#param-${CSS.escape(p.name)}`).value = toSlider(p, state.values[p.name]);
      $(`#value-${CSS.escape(p.name)}`).value = num(state.values[p.name], 5);
    }
    requestPrediction(event.timeStamp);
  });

  // ---------------------------------------------------------------- explore: prediction
  // At most one prediction in flight; inputs that arrive meanwhile are coalesced and the latest
  // slider values are sent as soon as the running request returns. Each input's latency ends when
  // a plot drawn from values at least as new as it has finished redrawing.
  const predictor = { inFlight: false, waiting: [] };

  function requestPrediction(inputTime) {
    predictor.waiting.push(inputTime ?? performance.now());
    if (!predictor.inFlight) sendPrediction();
  }

  async function sendPrediction() {
    predictor.inFlight = true;
    const covered = predictor.waiting;
    predictor.waiting = [];
    const values = {};
    for (const p of state.params) values[p.name] = state.values[p.name];
    try {
      const result = await api("POST", "/api/predict", { values });
      clearErrors($("#screen-explore"));
      await drawPrediction(result);
      const done = performance.now();
      for (const t of covered) window.podkrigLatency.push(done - t);
      window.podkrigPredictions += 1;
    } catch (err) {
      showError(err, $("#explore-error"));
    } finally {
      predictor.inFlight = false;
      if (predictor.waiting.length) sendPrediction();
    }
  }

  function buildTests() {
    for (const slot of state.plots) {
      if (slot.readings) slot.readings.forEach((r) => r.plot.destroy());
      if (slot.resid) slot.resid.destroy();
    }
    const box = $("#tests");
    box.replaceChildren();
    state.plots = [];
    state.tests.forEach((test, i) => {
      const upload = h("input", { type: "file", id: `upload-${i}`, accept: ".csv,.tsv,.txt,.xlsx", class: "upload" });
      upload.addEventListener("change", () => uploadMeasurement(i, upload));
      const panel = h("div", { class: "test", id: `test-${i}` },
        h("h3", {}, testLabel(test, i), " ", h("span", { class: "muted small", id: `chi2-${i}` })),
        h("div", { class: "small upload-line" },
          h("label", { for: `upload-${i}`, title: "CSV, TSV or Excel log, as podkrig invert reads; this session only" },
            "Replace the measurement: "), upload,
          h("span", { class: "muted", id: `upload-note-${i}` })),
        h("div", { class: "error", id: `err-upload-${i}`, role: "alert" }),
        h("div", { class: "legend", id: `legend-${i}` }),
        h("div", { id: `plot-${i}` }),
        h("div", { class: "axis-note", text: "Standardized residuals (measured − predicted)/σ per sensor; |r| > 2 is unusual." }),
        h("div", { id: `resid-${i}` }));
      box.append(panel);
      state.plots.push({ readings: null, resid: null });
    });
  }

  // A measurement log replaces the test's data for this session (the server reads and checks it
  // with the study's reader); the page then predicts again against it.
  async function uploadMeasurement(i, input) {
    const file = input.files && input.files[0];
    if (!file) return;
    const box = $(`#err-upload-${i}`);
    box.textContent = "";
    const test = state.tests[i];
    const query = `test=${encodeURIComponent(test.name ?? "")}&name=${encodeURIComponent(file.name)}`;
    try {
      const response = await fetch(`/api/measurement?${query}`, {
        method: "POST", headers: { "Content-Type": "application/octet-stream" }, body: file,
      });
      const data = await response.json().catch(() => ({ error: `${response.status} ${response.statusText}` }));
      if (!response.ok) throw new ApiError(data.error, data.field, response.status);
      state.tests[i] = Object.assign({}, test, data);
      $(`#upload-note-${i}`).textContent = ` now: ${file.name} (this session only)`;
      requestPrediction();
    } catch (err) {
      box.textContent = err.message;
    } finally {
      input.value = "";
    }
  }

  // The session's uploads (/api/study "uploads"): the file in use beside its test, or why it was
  // dropped when a job rebuilt the surrogates.
  function showUploads(study) {
    const uploads = study.uploads || {};
    state.tests.forEach((test, i) => {
      const upload = uploads[test.name ?? ""];
      const note = $(`#upload-note-${i}`);
      if (!note) return;
      note.textContent = upload && upload.state === "in use" ? ` now: ${upload.file} (this session only)` : "";
      if (upload && upload.state === "dropped") $(`#err-upload-${i}`).textContent = upload.message;
    });
  }

  function plotWidth(container) {
    return Math.max(300, Math.floor(container.getBoundingClientRect().width || 440) - 4);
  }

  // One readings plot per sensor unit in a test: measured points, predicted mean, ±2σ band.
  function readingsOptions(series, unitLabel, xLabel, width, drawn) {
    const opts = {
      width, height: 260,
      legend: { show: false },
      cursor: { drag: { x: false, y: false } },
      scales: { x: { time: false } },
      axes: [{ label: xLabel }, { label: unitLabel, size: 70 }],
      series: [{}],
      bands: [],
      hooks: { draw: [drawn] },
    };
    series.forEach((se, k) => {
      const c = color(k);
      const base = opts.series.length;
      opts.series.push(
        { label: `${se.sensor} measured`, stroke: c, width: 0, paths: () => null, points: { show: true, size: 7, fill: c, stroke: c } },
        { label: `${se.sensor} predicted`, stroke: c, width: 1.5, points: { show: false } },
        { label: `${se.sensor} +2σ`, stroke: rgba(c, 0.25), width: 0.5, points: { show: false } },
        { label: `${se.sensor} −2σ`, stroke: rgba(c, 0.25), width: 0.5, points: { show: false } });
      opts.bands.push({ series: [base + 2, base + 3], fill: rgba(c, 0.12) });
    });
    return opts;
  }

  function readingsData(series) {
    const data = [series[0].x.slice()];
    for (const se of series) {
      data.push(se.measured, se.mean,
        se.mean.map((m, j) => m + 2 * se.std[j]), se.mean.map((m, j) => m - 2 * se.std[j]));
    }
    return data;
  }

  function residOptions(series, xLabel, width, drawn) {
    const opts = {
      width, height: 170,
      legend: { show: false },
      cursor: { drag: { x: false, y: false } },
      scales: { x: { time: false }, y: { range: (u, lo, hi) => [Math.min(-3, lo - 0.3), Math.max(3, hi + 0.3)] } },
      axes: [{ label: xLabel }, { label: "(d − g)/σ [-]", size: 70 }],
      series: [{},
        { label: "+2", stroke: "#999", dash: [4, 4], width: 1, points: { show: false } },
        { label: "−2", stroke: "#999", dash: [4, 4], width: 1, points: { show: false } }],
      hooks: { draw: [drawn] },
    };
    series.forEach((se, k) => {
      opts.series.push({ label: se.sensor, stroke: color(k), width: 1, points: { show: true, size: 6, fill: color(k) } });
    });
    return opts;
  }

  function residData(series) {
    const x = series[0].x.slice();
    return [x, x.map(() => 2), x.map(() => -2), ...series.map((se) => se.residual)];
  }

  // Draw one /api/predict answer; resolves once every plot has redrawn.
  function drawPrediction(result) {
    const pending = [];
    const waitDraw = (u) => new Promise((resolve) => { u._podkrigDrawn = resolve; });
    const onDraw = (u) => { if (u._podkrigDrawn) { const f = u._podkrigDrawn; u._podkrigDrawn = null; f(); } };

    $("#chi2").textContent = `χ²/dof = ${num(result.chi2_dof, 3)}  (χ² = ${num(result.chi2, 4)} over ${result.dof} dof, ω = ${num(result.omega, 4)})`;
    result.tests.forEach((t, i) => {
      const slot = state.plots[i];
      if (!slot) return;
      $(`#chi2-${i}`).textContent = `χ²/dof = ${num(t.chi2_dof, 3)}`;
      const xUnit = t.series.length ? t.series[0].x_unit : "";
      const xLabel = `${state.tests[i].control || "control"} ${bracketUnit(xUnit)}`;
      // group sensors by unit: one readings plot per unit
      const groups = new Map();
      for (const se of t.series) {
        if (!groups.has(se.unit)) groups.set(se.unit, []);
        groups.get(se.unit).push(se);
      }
      const shape = Array.from(groups.entries()).map(([u, ss]) => `${u}:${ss.map((x) => x.sensor).join(",")}`).join("|");
      if (!slot.readings || slot.shape !== shape) {
        const box = $(`#plot-${i}`);
        box.replaceChildren();
        if (slot.readings) slot.readings.forEach((r) => r.plot.destroy());
        if (slot.resid) slot.resid.destroy();
        slot.readings = [];
        slot.shape = shape;
        const width = plotWidth($(`#test-${i}`));
        for (const [unit, ss] of groups) {
          const holder = h("div");
          box.append(holder);
          const plot = new uPlot(readingsOptions(ss, `reading ${bracketUnit(unit)}`, xLabel, width, onDraw), readingsData(ss), holder);
          slot.readings.push({ unit, plot });
        }
        const residBox = $(`#resid-${i}`);
        residBox.replaceChildren();
        slot.resid = new uPlot(residOptions(t.series, xLabel, width, onDraw), residData(t.series), residBox);
        const legend = $(`#legend-${i}`);
        legend.replaceChildren(
          ...t.series.map((se, k) => h("span", {}, h("i", { style: `background:${color(k)}` }), `${se.sensor} ${bracketUnit(se.unit)}`)),
          h("span", { class: "muted" }, "● measured, — predicted, band ±2σ of the surrogate"));
        return;   // new plots draw synchronously on creation
      }
      for (const r of slot.readings) {
        pending.push(waitDraw(r.plot));
        r.plot.setData(readingsData(groups.get(r.unit)));
      }
      pending.push(waitDraw(slot.resid));
      slot.resid.setData(residData(t.series));
    });
    // uPlot redraws in a microtask; a frame later is the latest it can be (e.g. unchanged scales)
    const fallback = new Promise((resolve) => requestAnimationFrame(() => resolve()));
    return pending.length ? Promise.race([Promise.all(pending), fallback]) : Promise.resolve();
  }

  function resizePlots() {
    state.plots.forEach((slot, i) => {
      const panel = $(`#test-${i}`);
      if (!panel || !slot.readings) return;
      const width = plotWidth(panel);
      for (const r of slot.readings) r.plot.setSize({ width, height: 260 });
      slot.resid.setSize({ width, height: 170 });
    });
  }
  let resizeTimer = null;
  window.addEventListener("resize", () => {
    clearTimeout(resizeTimer);
    resizeTimer = setTimeout(() => { resizePlots(); if (state.fe && state.fe.curvePlot) resizeCurve(); }, 150);
  });

  // ---------------------------------------------------------------- calibrate: settings
  function field(id, label, unit, value, attrs) {
    return h("div", { class: "field" },
      h("label", { for: id }, label, unit ? ` ${bracketUnit(unit)}` : ""),
      h("input", Object.assign({ id, type: "number", step: "any", value: value ?? "" }, attrs || {})),
      h("div", { class: "error", id: `err-${id.replace(/^inv-/, "")}`, role: "alert" }));
  }

  const INVERSION_FIELDS = [
    ["seed", "seed", "", { step: 1, min: 0 }],
    ["population_size", "population size", "", { step: 1, min: 1 }],
    ["generations", "generations", "", { step: 1, min: 1 }],
    ["n_starts", "independent starts", "", { step: 1, min: 1 }],
  ];

  function buildCalibrateForm() {
    const inv = state.study.inversion || {};
    $("#inversion-fields").replaceChildren(...INVERSION_FIELDS.map(([key, label, unit, attrs]) =>
      field(`inv-${key}`, label, unit, inv[key], attrs)));
    const noise = state.study.noise || {};
    const keys = Object.keys(noise);
    const rows = [];
    keys.forEach((key, i) => {
      const n = noise[key] || {};
      const test = state.tests.find((t) => (t.name ?? "") === key);
      const units = test ? Array.from(new Set(test.sensors.map((x) => x.unit))).join(", ") : "sensor unit";
      rows.push(h("div", { class: "small muted", text: key === "" ? "every test" : `test ${key}` }));
      const rel = field(`noise-${i}-noise_rel`, "relative σ", "-", n.noise_rel, { min: 0 });
      const abs = field(`noise-${i}-noise_abs`, `absolute σ`, units, n.noise_abs, { min: 0 });
      rel.querySelector("input").dataset.noiseKey = key;
      abs.querySelector("input").dataset.noiseKey = key;
      rel.querySelector(".error").id = `err-noise-${i}-noise_rel`;
      abs.querySelector(".error").id = `err-noise-${i}-noise_abs`;
      rows.push(rel, abs);
      if (n.instrument) rows.push(h("div", { class: "small muted", text: `instrument: ${n.instrument}` }));
    });
    $("#noise-fields").replaceChildren(...(rows.length ? rows : [h("span", { class: "small muted", text: "the study's noise model" })]));
  }

  function renderFrozen() {
    const box = $("#frozen-list");
    if (!box || !state.params.length) return;
    if (!state.locked.size) {
      box.replaceChildren(h("span", { class: "muted", text: "none — lock parameters on the Explore screen to freeze them" }));
      return;
    }
    box.replaceChildren(...Array.from(state.locked).map((name) => {
      const p = state.params.find((q) => q.name === name);
      return h("div", {}, `${name} = ${withUnit(state.values[name], p.unit, 5)}`);
    }));
  }

  function frozenValues() {
    const frozen = {};
    for (const name of state.locked) frozen[name] = state.values[name];
    return frozen;
  }

  function readCalibrationBody() {
    const inversion = {};
    for (const [key] of INVERSION_FIELDS) {
      const raw = $(`#inv-${key}`).value.trim();
      if (raw !== "") inversion[key] = Number(raw);
    }
    let noise = null;
    for (const input of $$("#noise-fields input")) {
      const key = input.dataset.noiseKey;
      const name = input.id.endsWith("noise_rel") ? "noise_rel" : "noise_abs";
      const raw = input.value.trim();
      if (raw === "") continue;
      noise = noise || {};
      noise[key] = noise[key] || {};
      noise[key][name] = Number(raw);
    }
    return { frozen: frozenValues(), noise, inversion, diagnosis: $("#calib-diagnosis").checked };
  }

  // ---------------------------------------------------------------- calibrate: run
  $("#calib-form").addEventListener("submit", async (event) => {
    event.preventDefault();
    clearErrors($("#screen-calibrate"));
    const button = $("#calibrate");
    button.disabled = true;
    const clicked = event.timeStamp;
    $("#calib-status").dataset.status = "starting";
    try {
      const { run } = await api("POST", "/api/calibrate", readCalibrationBody());
      $("#calib-status").textContent = "running";
      const finished = await followRun(run);
      if (finished.status === "done") window.podkrigCalibration.push(performance.now() - clicked);
    } catch (err) {
      $("#calib-status").textContent = "";
      $("#calib-status").dataset.status = "refused";
      showError(err, $("#calib-error"));
    } finally {
      button.disabled = false;
    }
  });

  async function followRun(id) {
    const t0 = performance.now();
    for (;;) {
      const run = await api("GET", `/api/runs/${encodeURIComponent(id)}`);
      const p = run.progress || {};
      const bar = $("#calib-progress");
      bar.max = p.total || 1;
      bar.value = Math.min(p.done || 0, bar.max);
      const secs = ((performance.now() - t0) / 1000).toFixed(1);
      $("#calib-status").textContent = run.status === "running"
        ? `running${p.step ? ` — ${p.step}` : ""} ${p.done ?? 0}/${p.total ?? "?"} (${secs} s)` : run.status;
      $("#calib-status").dataset.status = run.status;
      if (run.status !== "running") {
        bar.value = bar.max;
        if (run.status === "failed") {
          $("#calib-error").textContent = run.error || "the calibration failed";
        } else {
          showRun(run);
        }
        await refreshRuns();
        return run;
      }
      await sleep(50);
    }
  }

  function showRun(run, title) {
    state.shownRun = run.id || null;
    state.shownRunData = run;
    const r = run.result;
    $("#result-title").textContent = title || `Result of run ${run.id}`;
    const exportLink = $("#export");
    if (run.id) {
      exportLink.href = `/api/runs/${encodeURIComponent(run.id)}/summary.json`;
      exportLink.setAttribute("download", `summary-${run.id}.json`);
      exportLink.hidden = false;
    } else {
      exportLink.hidden = true;
    }
    if (!r) return;
    const frozen = Object.entries(run.frozen || {});
    $("#calib-summary").replaceChildren(
      h("span", {}, `χ²/dof = ${num(r.chi2_dof, 3)} over ${r.dof} dof · ${num(r.seconds, 3)} s · ${r.n_fe_runs ?? 0} FE run(s)`),
      frozen.length ? h("span", {}, ` · frozen: ${frozen.map(([k, v]) => `${k} = ${withUnit(v, unitOf(k), 5)}`).join(", ")}`) : "");
    const table = $("#results");
    table.replaceChildren(
      h("tr", {}, h("th", { text: "parameter" }), h("th", { text: "best" }), h("th", { text: "95 % interval" }),
        h("th", { text: "identified" }), h("th", { text: "" })),
      ...r.parameters.map((p) => h("tr", { "data-param": p.name },
        h("td", { text: p.name }),
        h("td", { class: "num", text: withUnit(p.value, p.unit) }),
        h("td", { class: "num", text: p.interval ? `${num(p.interval[0])} – ${num(p.interval[1])} ${unitText(p.unit)}` : "–" }),
        h("td", { class: p.identified === null ? "" : p.identified ? "yes" : "no",
          text: p.identified === null || p.identified === undefined ? "–" : p.identified ? "yes" : "no" }),
        h("td", { class: "small", text: p.words || "" }))),
      ...frozen.filter(([name]) => !r.parameters.some((p) => p.name === name)).map(([name, value]) =>
        h("tr", { "data-param": name, class: "frozen" },
          h("td", { text: name }),
          h("td", { class: "num", text: withUnit(value, unitOf(name)) }),
          h("td", { class: "num", text: "–" }),
          h("td", { text: "frozen" }),
          h("td", { class: "small", text: "held at this value (locked on the Explore screen)" }))));
    drawRegion(r.region);
    const fe = r.fe_check || [];
    $("#fe-check").replaceChildren(...(fe.length ? [
      h("tr", {}, h("th", { text: "test" }), h("th", { text: "max |FE − surrogate|" }),
        h("th", { text: "÷ noise σ" }), h("th", { text: "χ²/dof of the FE model" }), h("th", { text: "verdict" })),
      ...fe.map((row) => h("tr", { "data-test": row.test ?? "" },
        h("td", { text: row.test || "the test" }),
        h("td", { class: "num", text: withUnit(row.max_diff, row.unit) }),
        h("td", { class: "num", text: row.max_diff_over_noise === undefined ? "–" : `${num(row.max_diff_over_noise, 3)} [-]` }),
        h("td", { class: "num", text: row.chi2_dof_fe === undefined ? "–" : num(row.chi2_dof_fe, 3) }),
        h("td", { class: row.ok === false ? "no" : "yes",
          text: row.ok === false ? "the surrogate misses the FE model" : "the surrogate agrees" })))]
      : [h("tr", {}, h("td", { class: "muted", text: "no FE check in this run" }))]));
    $("#findings").replaceChildren(...((r.findings || []).map((f) => h("li", {}, h("code", { text: f.code }), " ", f.message))));
    renderDiagnosis(r.diagnosis);
    $$("#runs tr[data-run]").forEach((tr) => tr.classList.toggle("selected", tr.dataset.run === state.shownRun));
  }

  function unitOf(name) {
    const p = state.params.find((q) => q.name === name);
    return p ? p.unit : "";
  }

  function renderDiagnosis(diagnosis) {
    const box = $("#diagnosis");
    if (!diagnosis) {
      box.className = "small muted";
      box.textContent = "Not run: tick “run the model diagnosis” before calibrating.";
      return;
    }
    box.className = "small";
    box.replaceChildren(renderValue(diagnosis, 0));
  }

  // A nested result as nested lists: scalars inline, objects and arrays indented.
  function renderValue(value, depth) {
    if (value === null || typeof value !== "object") {
      return document.createTextNode(typeof value === "number" ? num(value) : String(value));
    }
    if (Array.isArray(value) && value.every((v) => v === null || typeof v !== "object")) {
      return document.createTextNode(value.map((v) => (typeof v === "number" ? num(v) : String(v))).join(", "));
    }
    const list = h("ul", { class: depth ? "" : "plain" });
    const entries = Array.isArray(value) ? value.map((v, i) => [String(i + 1), v]) : Object.entries(value);
    for (const [key, v] of entries.slice(0, 60)) {
      list.append(h("li", {}, h("b", { text: `${key}: ` }), depth < 4 ? renderValue(v, depth + 1) : "…"));
    }
    return list;
  }

  // Region of equivalence as a pair plot on a canvas (log axes for log-scaled parameters).
  function drawRegion(region) {
    const canvas = $("#region");
    const ctx = canvas.getContext("2d");
    const W = canvas.width;
    ctx.clearRect(0, 0, W, canvas.height);
    if (!region || !region.samples || !region.samples.length) {
      ctx.fillStyle = "#667085";
      ctx.font = "13px sans-serif";
      ctx.fillText("no region in this run", 20, 30);
      return;
    }
    const names = region.names;
    const n = names.length;
    const pad = 46;
    const cell = (W - pad) / n;
    const scales = names.map((name, j) => {
      const p = state.params.find((q) => q.name === name);
      const log = p && p.scale === "log";
      const f = (v) => (log ? Math.log10(v) : v);
      const vals = region.samples.map((row) => f(row[j])).concat(region.best ? [f(region.best[j])] : []);
      // the members' range with a margin (the region is often a small part of the search box)
      let lo = Math.min(...vals);
      let hi = Math.max(...vals);
      const margin = hi > lo ? 0.08 * (hi - lo) : Math.abs(hi) * 0.01 || 1;
      lo -= margin;
      hi += margin;
      return { f, lo, hi, log };
    });
    const pos = (j, v) => (scales[j].f(v) - scales[j].lo) / (scales[j].hi - scales[j].lo);
    ctx.font = "11px sans-serif";
    for (let row = 0; row < n; row++) {
      for (let col = 0; col < n; col++) {
        const x0 = pad + col * cell;
        const y0 = row * cell;
        ctx.strokeStyle = "#d7dce3";
        ctx.strokeRect(x0 + 2, y0 + 2, cell - 4, cell - 4);
        const inner = cell - 10;
        if (row === col) {
          const bins = new Array(12).fill(0);
          for (const sample of region.samples) {
            bins[Math.min(11, Math.floor(pos(col, sample[col]) * 12))] += 1;
          }
          const top = Math.max(...bins);
          ctx.fillStyle = "rgba(31,95,191,0.45)";
          bins.forEach((b, k) => {
            const bh = (b / top) * inner;
            ctx.fillRect(x0 + 5 + (k * inner) / 12, y0 + 5 + inner - bh, inner / 12 - 1, bh);
          });
        } else {
          ctx.fillStyle = "rgba(80,80,80,0.35)";
          for (const sample of region.samples) {
            const px = x0 + 5 + pos(col, sample[col]) * inner;
            const py = y0 + 5 + (1 - pos(row, sample[row])) * inner;
            ctx.fillRect(px - 1, py - 1, 2.5, 2.5);
          }
          if (region.best) {
            ctx.fillStyle = "#d62728";
            const px = x0 + 5 + pos(col, region.best[col]) * inner;
            const py = y0 + 5 + (1 - pos(row, region.best[row])) * inner;
            ctx.beginPath();
            ctx.arc(px, py, 4, 0, 2 * Math.PI);
            ctx.fill();
          }
        }
      }
    }
    ctx.fillStyle = "#1d2430";
    names.forEach((name, j) => {
      const unit = (region.units && region.units[j]) || unitOf(name);
      const label = `${name} ${bracketUnit(unit)}${scales[j].log ? " log" : ""}`;
      ctx.save();
      ctx.translate(14, j * cell + cell / 2);
      ctx.rotate(-Math.PI / 2);
      ctx.textAlign = "center";
      ctx.fillText(label, 0, 0);
      ctx.restore();
      ctx.textAlign = "center";
      ctx.fillText(label, pad + j * cell + cell / 2, W - pad + 18);
      const lo = scales[j].log ? 10 ** scales[j].lo : scales[j].lo;
      const hi = scales[j].log ? 10 ** scales[j].hi : scales[j].hi;
      ctx.fillStyle = "#667085";
      ctx.fillText(`${num(lo, 3)} … ${num(hi, 3)}`, pad + j * cell + cell / 2, W - pad + 32);
      ctx.fillStyle = "#1d2430";
    });
    ctx.textAlign = "start";
  }

  // ---------------------------------------------------------------- calibrate: history and comparison
  async function refreshRuns() {
    let runs;
    try {
      runs = await api("GET", "/api/runs");
    } catch (err) {
      showError(err, $("#calib-error"));
      return;
    }
    const picked = new Set($$("#runs .compare-pick:checked").map((c) => c.value));
    const table = $("#runs");
    table.replaceChildren(
      h("tr", {}, h("th", { text: "compare" }), h("th", { text: "run" }), h("th", { text: "status" }),
        h("th", { text: "started" }), h("th", { text: "time" }), h("th", { text: "frozen" }),
        h("th", { text: "χ²/dof" }), h("th", { text: "" })),
      ...runs.map((run) => {
        const pick = h("input", { type: "checkbox", class: "compare-pick", value: run.id, "aria-label": `compare ${run.id}` });
        pick.checked = picked.has(run.id);
        pick.addEventListener("change", compareRuns);
        const frozen = Object.entries(run.frozen || {}).map(([k, v]) => `${k} = ${withUnit(v, unitOf(k))}`).join(", ");
        return h("tr", { "data-run": run.id, class: run.id === state.shownRun ? "selected" : "" },
          h("td", {}, pick),
          h("td", { text: run.id }),
          h("td", { text: run.status }),
          h("td", { text: formatTime(run.started) }),
          h("td", { class: "num", text: run.seconds === null || run.seconds === undefined ? "–" : `${num(run.seconds, 3)} s` }),
          h("td", { class: "small", text: frozen || "none" }),
          h("td", { class: "num", text: num(run.chi2_dof, 3) }),
          h("td", {}, run.status === "done"
            ? h("button", { type: "button", class: "small", onclick: () => openRun(run.id) }, "show") : ""));
      }));
    compareRuns();
  }

  function formatTime(started) {
    if (started === null || started === undefined) return "–";
    const d = typeof started === "number" ? new Date(started * 1000) : new Date(started);
    return Number.isNaN(d.getTime()) ? String(started) : d.toLocaleTimeString();
  }

  async function openRun(id) {
    try {
      showRun(await api("GET", `/api/runs/${encodeURIComponent(id)}`));
    } catch (err) {
      showError(err, $("#calib-error"));
    }
  }

  async function compareRuns() {
    const ids = $$("#runs .compare-pick:checked").map((c) => c.value);
    const table = $("#compare");
    if (ids.length !== 2) {
      table.replaceChildren(...(ids.length > 2 ? [h("tr", {}, h("td", { class: "muted", text: "tick exactly two runs" }))] : []));
      return;
    }
    let a;
    let b;
    try {
      [a, b] = await Promise.all(ids.map((id) => api("GET", `/api/runs/${encodeURIComponent(id)}`)));
    } catch (err) {
      showError(err, $("#calib-error"));
      return;
    }
    if (!a.result || !b.result) {
      table.replaceChildren(h("tr", {}, h("td", { class: "muted", text: "both runs must be done" })));
      return;
    }
    const cell = (p) => (p ? `${withUnit(p.value, p.unit)}  [${p.interval ? `${num(p.interval[0])} – ${num(p.interval[1])}` : "–"}]${p.identified ? "" : " (not identified)"}` : "–");
    const names = Array.from(new Set([...a.result.parameters, ...b.result.parameters].map((p) => p.name)));
    const frozenText = (run) => Object.entries(run.frozen || {}).map(([k, v]) => `${k} = ${withUnit(v, unitOf(k))}`).join(", ") || "none";
    const settingsText = (run) => {
      const inv = (run.settings && run.settings.inversion) || {};
      return Object.entries(inv).map(([k, v]) => `${k} ${v}`).join(", ") || "study defaults";
    };
    table.replaceChildren(
      h("tr", {}, h("th", { text: "" }), h("th", { text: `run ${a.id}` }), h("th", { text: `run ${b.id}` })),
      h("tr", {}, h("td", { text: "χ²/dof" }), h("td", { class: "num", text: num(a.result.chi2_dof, 3) }), h("td", { class: "num", text: num(b.result.chi2_dof, 3) })),
      h("tr", {}, h("td", { text: "frozen" }), h("td", { text: frozenText(a) }), h("td", { text: frozenText(b) })),
      h("tr", {}, h("td", { text: "GA" }), h("td", { text: settingsText(a) }), h("td", { text: settingsText(b) })),
      ...names.map((name) => h("tr", { "data-param": name }, h("td", { text: name }),
        h("td", { class: "num", text: cell(a.result.parameters.find((p) => p.name === name)) }),
        h("td", { class: "num", text: cell(b.result.parameters.find((p) => p.name === name)) }))));
  }

  // ---------------------------------------------------------------- model: FE on demand
  state.fe = null;

  function feValues() {
    if ($("#fe-source").value === "best") {
      // the best fit of the calibration on the Calibrate screen (its frozen values included),
      // else the study's
      const values = {};
      for (const p of state.params) values[p.name] = p.best ?? p.value;
      const run = state.shownRunData;
      if (run && run.result) {
        Object.assign(values, run.frozen || {});
        for (const p of run.result.parameters) values[p.name] = p.value;
      }
      return values;
    }
    return Object.assign({}, state.values);
  }

  $("#fe-run").addEventListener("click", async () => {
    clearErrors($("#screen-model"));
    const button = $("#fe-run");
    button.disabled = true;
    const status = $("#fe-status");
    const t0 = performance.now();
    try {
      const testIndex = Number($("#fe-test").value || 0);
      const test = state.tests[testIndex];
      const { fe } = await api("POST", "/api/fe", { values: feValues(), test: test ? test.name : null });
      for (;;) {
        const answer = await api("GET", `/api/fe/${encodeURIComponent(fe)}`);
        if (answer.status === "running") {
          status.className = "small pending";
          status.textContent = `pending — the FE solver is running (${((performance.now() - t0) / 1000).toFixed(1)} s)`;
          await sleep(250);
          continue;
        }
        if (answer.status === "failed") throw new ApiError(answer.error || "the FE run failed", null, 500);
        status.className = "small";
        status.textContent = `done in ${((performance.now() - t0) / 1000).toFixed(1)} s`;
        showFE(answer.result, answer.parameters);
        break;
      }
    } catch (err) {
      status.className = "small";
      status.textContent = "";
      showError(err, $("#fe-error"));
    } finally {
      button.disabled = false;
    }
  });

  function showFE(result, parameters) {
    const nodes = result.nodes;
    let xmin = Infinity; let xmax = -Infinity; let ymin = Infinity; let ymax = -Infinity;
    for (const [x, y] of nodes) {
      xmin = Math.min(xmin, x); xmax = Math.max(xmax, x); ymin = Math.min(ymin, y); ymax = Math.max(ymax, y);
    }
    const span = Math.max(xmax - xmin, ymax - ymin) || 1;
    // joints follow the displacement of the node nearest to each end
    const nearest = (pt) => {
      let best = 0; let dist = Infinity;
      nodes.forEach(([x, y], k) => {
        const d = (x - pt[0]) ** 2 + (y - pt[1]) ** 2;
        if (d < dist) { dist = d; best = k; }
      });
      return best;
    };
    const joints = (result.joints || []).map((j) => Object.assign({ na: nearest(j.a), nb: nearest(j.b) }, j));
    const svg = $("#mesh");
    const margin = 0.15 * span;
    // SVG y grows downwards: draw (x, −y)
    svg.setAttribute("viewBox", `${xmin - margin} ${-ymax - margin} ${xmax - xmin + 2 * margin} ${ymax - ymin + 2 * margin}`);
    const ghost = s("g", { fill: "none", stroke: "#c9ced6", "stroke-width": span / 900 });
    const deformed = s("g", { fill: "rgba(31,95,191,0.08)", stroke: "#1f5fbf", "stroke-width": span / 700 });
    const jointLayer = s("g", { "stroke-width": span / 180, "stroke-linecap": "round" });
    const polys = result.outline.map((ring) => {
      ghost.append(s("polygon", { points: ring.map((k) => `${nodes[k][0]},${-nodes[k][1]}`).join(" ") }));
      const poly = s("polygon", {});
      deformed.append(poly);
      return poly;
    });
    const lines = joints.map(() => {
      const line = s("line", {});
      jointLayer.append(line);
      return line;
    });
    svg.replaceChildren(ghost, deformed, jointLayer);
    const n = result.steps.length;
    const stepInput = $("#fe-step");
    stepInput.max = Math.max(0, n - 1);
    stepInput.value = Math.max(0, n - 1);
    $("#fe-scale").value = num(result.scale, 3);
    state.fe = { result, polys, lines, joints, span, parameters, curvePlot: null };
    buildCurve(result);
    redrawFE();
  }

  function redrawFE() {
    const fe = state.fe;
    if (!fe) return;
    const { result, polys, lines, joints } = fe;
    const k = Number($("#fe-step").value);
    const scale = Number($("#fe-scale").value) || 0;
    const u = result.displacement[k];
    const nodes = result.nodes;
    const at = (i) => [nodes[i][0] + scale * u[i][0], -(nodes[i][1] + scale * u[i][1])];
    result.outline.forEach((ring, e) => {
      polys[e].setAttribute("points", ring.map((i) => at(i).join(",")).join(" "));
    });
    const kind = $("#fe-joint-kind").value;
    let top = 0;
    for (const j of joints) top = Math.max(top, ...j[kind].map(Math.abs));
    joints.forEach((j, q) => {
      const a = at(j.na);
      const b = at(j.nb);
      const v = Math.abs(j[kind][k]);
      const t = top > 0 ? v / top : 0;
      lines[q].setAttribute("x1", a[0]); lines[q].setAttribute("y1", a[1]);
      lines[q].setAttribute("x2", b[0]); lines[q].setAttribute("y2", b[1]);
      lines[q].setAttribute("stroke", `rgba(214,39,40,${(0.05 + 0.95 * t).toFixed(3)})`);
    });
    $("#fe-joint-legend").textContent = joints.length
      ? `red joints: ${kind}, darkest = ${withUnit(top, "mm")} (at step ${k + 1}: up to ${withUnit(Math.max(0, ...joints.map((j) => Math.abs(j[kind][k]))), "mm")})`
      : "linear scenario: no joint opening or slip";
    $("#fe-step-label").textContent = `${k + 1}/${result.steps.length}: ${withUnit(result.steps[k], result.x_unit)}`;
    const ran = Object.entries(fe.parameters || {}).map(([name, v]) => `${name} = ${withUnit(v, unitOf(name))}`).join(", ");
    $("#mesh-caption").textContent = `Deformed mesh at step ${k + 1} (${withUnit(result.steps[k], result.x_unit)}), displacements magnified ×${num(scale, 3)}; grey: undeformed; coordinates in mm.${ran ? ` FE model at ${ran}.` : ""}`;
    if (fe.curvePlot) fe.curvePlot.setData(curveData(result, k));
  }

  // The curve in ascending displacement (uPlot needs sorted x), the current step marked.
  function curveData(result, k) {
    const c = result.curve;
    const order = c.x.map((x, i) => i).sort((a, b) => c.x[a] - c.x[b]);
    const mark = c.step_index[k];  // the shown step's own point of the curve (the curve has every step)
    return [order.map((i) => c.x[i]), order.map((i) => c.y[i]), order.map((i) => (i === mark ? c.y[i] : null))];
  }

  function buildCurve(result) {
    const box = $("#fe-curve");
    box.replaceChildren();
    if (!result.curve) {
      box.append(h("p", { class: "small muted", text: "this scenario has no load–displacement curve" }));
      return;
    }
    const c = result.curve;
    const opts = {
      width: plotWidth(box), height: 240,
      legend: { show: false },
      scales: { x: { time: false } },
      axes: [{ label: `displacement ${bracketUnit(c.x_unit)}` }, { label: `load ${bracketUnit(c.y_unit)}`, size: 70 }],
      series: [{}, { stroke: "#1f5fbf", width: 1.5, points: { show: true, size: 4 } },
        { stroke: "#d62728", width: 0, paths: () => null, points: { show: true, size: 10, fill: "#d62728" } }],
    };
    state.fe.curvePlot = new uPlot(opts, curveData(result, Number($("#fe-step").value)), box);
  }

  function resizeCurve() {
    const box = $("#fe-curve");
    state.fe.curvePlot.setSize({ width: plotWidth(box), height: 240 });
  }

  $("#fe-step").addEventListener("input", redrawFE);
  $("#fe-scale").addEventListener("input", redrawFE);
  $("#fe-joint-kind").addEventListener("change", redrawFE);

  // ---------------------------------------------------------------- jobs
  $("#job-start").addEventListener("click", async () => {
    clearErrors($("#screen-jobs"));
    try {
      const { job } = await api("POST", "/api/jobs", { kind: "study", skip_diagnosis: $("#job-skip-diagnosis").checked });
      followJob(job);
    } catch (err) {
      showError(err, $("#job-error"));
    }
  });

  $("#job-cancel").addEventListener("click", async () => {
    if (!state.job) return;
    try {
      await api("DELETE", `/api/jobs/${encodeURIComponent(state.job)}`);
    } catch (err) {
      showError(err, $("#job-error"));
    }
  });

  async function followJob(id) {
    state.job = id;
    refreshJobs();
    $("#job-start").disabled = true;
    $("#job-cancel").disabled = false;
    try {
      for (;;) {
        const job = await api("GET", `/api/jobs/${encodeURIComponent(id)}`);
        const p = job.progress || {};
        const bar = $("#job-progress");
        bar.max = p.total || 1;
        bar.value = Math.min(p.done || 0, bar.max);
        const status = $("#job-status");
        status.dataset.status = job.status;
        status.textContent = job.status === "running"
          ? `running${p.stage ? ` — ${p.stage}` : ""} ${p.done ?? 0}/${p.total ?? "?"}` : job.status;
        const log = $("#job-log");
        log.textContent = (job.log || []).join("\n");
        log.scrollTop = log.scrollHeight;
        if (job.error) $("#job-error").textContent = job.error;
        if (job.status !== "running") {
          if (job.status === "done") bar.value = bar.max;
          break;
        }
        await sleep(400);
      }
    } catch (err) {
      showError(err, $("#job-error"));
    } finally {
      $("#job-start").disabled = false;
      $("#job-cancel").disabled = true;
      await refreshJobs();
      await reloadStudyIfChanged();
    }
  }

  async function refreshJobs() {
    let jobs;
    try {
      jobs = await api("GET", "/api/jobs");
    } catch (err) {
      showError(err, $("#job-error"));
      return [];
    }
    $("#jobs").replaceChildren(
      h("tr", {}, h("th", { text: "job" }), h("th", { text: "kind" }), h("th", { text: "status" }),
        h("th", { text: "started" }), h("th", { text: "progress or time" })),
      ...jobs.map((job) => {
        const p = job.progress || {};
        const progress = job.status === "running" ? `${p.stage ?? ""} ${p.done ?? 0}/${p.total ?? "?"}`
          : (job.seconds === null || job.seconds === undefined ? "–" : `${num(job.seconds, 3)} s`);
        return h("tr", { "data-job": job.id }, h("td", { text: job.id }), h("td", { text: job.kind ?? "study" }),
          h("td", { text: job.status }), h("td", { text: formatTime(job.started) }), h("td", { class: "num", text: progress }));
      }));
    return jobs;
  }

  // After a job the server reads the folder again: a new state or parameter set rebuilds the page,
  // otherwise the sliders keep their values and ask the new surrogate.
  async function reloadStudyIfChanged() {
    try {
      const study = await api("GET", "/api/study");
      const names = (s) => s.parameters.map((p) => `${p.name}:${p.lower}:${p.upper}:${p.scale}`).join("|");
      if (study.state !== state.study.state || names(study) !== names(state.study)) await start(study);
      else {
        showUploads(study);
        if (study.state === "ready") requestPrediction();
      }
    } catch (err) {
      showError(err, $("#job-error"));
    }
  }

  // ---------------------------------------------------------------- start
  function describeState(study) {
    document.body.dataset.state = study.state;
    const notice = $("#notice");
    if (study.state === "needs_offline") {
      notice.hidden = false;
      notice.textContent = "This study's offline stage has not run yet (no surrogate): start it on the Jobs screen; Explore and Calibrate work once it has finished.";
      $("#job-state").textContent = "The surrogate is missing: the offline stage must run first.";
    } else {
      notice.hidden = true;
      $("#job-state").textContent = "The study's stages are done; a new job reruns only what changed.";
    }
  }

  async function start(study) {
    state.study = study;
    state.params = study.parameters;
    state.tests = study.tests;
    state.values = {};
    for (const p of state.params) state.values[p.name] = p.value;
    state.locked = new Set();
    $("#study-name").textContent = study.name;
    $("#study-folder").textContent = study.folder;
    document.title = `podkrig serve — ${study.name}`;
    describeState(study);
    buildSliders();
    buildTests();
    showUploads(study);
    buildCalibrateForm();
    renderFrozen();
    $("#fe-test").replaceChildren(...state.tests.map((t, i) => h("option", { value: i, text: testLabel(t, i) })));
    if (study.calibration) showRun({ id: null, frozen: {}, result: study.calibration }, "Last calibration stored in the folder");
    const jobs = await refreshJobs();
    const running = jobs.find((j) => j.status === "running");
    if (running && state.job !== running.id) followJob(running.id);
    await refreshRuns();
    if (study.state === "ready") {
      predictor.waiting.push(performance.now());
      await sendPrediction();
    }
  }

  async function boot() {
    const asked = location.hash.replace(/^#\/?/, "");
    showScreen(asked || "explore");
    try {
      const study = await api("GET", "/api/study");
      if (study.state === "needs_offline" && !asked) showScreen("jobs");
      await start(study);
    } catch (err) {
      const notice = $("#notice");
      notice.hidden = false;
      notice.textContent = `The study could not be loaded: ${err.message}`;
    }
    document.body.dataset.ready = "1";
  }
  boot();
})();
