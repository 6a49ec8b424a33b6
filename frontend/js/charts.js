// Plotly charts, always drawn with Plotly.react so a redraw replaces the data in place.

// Plotly's own reference has hundreds of keys: traces and layouts are typed as open objects here, with
// the parts the charts change after building them (margins, axes, legend) as objects of their own.
/** @typedef {Record<string, unknown>} Trace one Plotly trace: type, x, y, line, ... */
/** @typedef {Record<string, unknown>} LayoutPart */
/**
 * A 2-D chart's layout (baseLayout), its parts open for a chart to change.
 * @typedef {{[key: string]: unknown, margin: LayoutPart, xaxis: LayoutPart, yaxis: LayoutPart, legend: LayoutPart}} Layout
 */
/**
 * The part of Plotly (vendor/plotly-*.min.js, window.Plotly) the dashboard calls.
 * @typedef {object} PlotlyLibrary
 * @property {(div: HTMLElement, traces: Trace[], layout: object, config: object) => Promise<HTMLElement>} react
 * @property {(div: HTMLElement) => void} purge
 */
/**
 * A chart's div: the bundle that drew it, and the chart waiting for it to be scrolled near.
 * @typedef {HTMLElement & {__plotly?: PlotlyLibrary, __pendingChart?: PendingChart}} ChartDiv
 */
/**
 * @typedef {object} PendingChart
 * @property {[Trace[], object, object]} args traces, layout, config
 * @property {{resolve: (div: HTMLElement) => void, reject: (error: unknown) => void}[]} waiters
 */

/** @type {Record<string, string>} */
export const AXIS_COLOURS = { x: "#1f5fa8", y: "#c2410c", z: "#2f855a" };
const VERSION_COLOURS = ["#1f5fa8", "#6b8fd6", "#c2410c", "#e8925c", "#2f855a", "#7cc29a"];
const FONT = { family: "system-ui, -apple-system, 'Segoe UI', Roboto, sans-serif", size: 12, color: "#1d2630" };

const CONFIG = {
  responsive: true,
  displaylogo: false,
  modeBarButtonsToRemove: ["lasso2d", "select2d", "autoScale2d"],
  toImageButtonOptions: { format: "png", scale: 2 },
};

// The pinned local Plotly (vendor/README.md) comes in two official bundles of one version: the
// cartesian one (1.4 MB: scatter, bar, heatmap, every 2-D chart here) is loaded on the first chart, the
// full one (4.8 MB, for scatter3d) only when a 3-D chart is drawn. Pages without charts (lists, forms)
// parse neither; each is fetched once per version (the server marks vendor/ immutable).
const PLOTLY_SRC = { cartesian: "vendor/plotly-cartesian-3.7.0.min.js", full: "vendor/plotly-3.7.0.min.js" };
/** @typedef {keyof PLOTLY_SRC} Bundle */
/** @type {Partial<Record<Bundle, Promise<PlotlyLibrary>>>} bundle name -> Promise of its Plotly */
const libraries = {};
/** @type {PlotlyLibrary | null} */
let lastLoaded = null; // both bundles set window.Plotly: each is kept as it was when its script ran
const withPlotly = /** @type {Window & {Plotly?: PlotlyLibrary}} */ (window);

/**
 * @param {Bundle} name
 * @returns {Promise<PlotlyLibrary>}
 */
function loadBundle(name) {
  if (!libraries[name]) {
    libraries[name] = new Promise((resolve, reject) => {
      const failed = () => {
        delete libraries[name]; // a later chart tries again (e.g. after a network hiccup)
        reject(new Error("The chart library (vendor/plotly) did not load."));
      };
      const script = document.createElement("script");
      script.src = PLOTLY_SRC[name];
      script.async = true;
      script.onload = () => {
        if (!withPlotly.Plotly || withPlotly.Plotly === lastLoaded) return failed();
        lastLoaded = withPlotly.Plotly;
        resolve(withPlotly.Plotly);
      };
      script.onerror = failed;
      document.head.append(script);
    });
  }
  return libraries[name];
}

/**
 * Fetch the cartesian bundle into the cache at low priority, without running it (app.js: once signed in,
 * when the browser is idle), so the first chart comes from the cache. The sign-in page never calls it.
 */
export function prefetchPlotly() {
  if (libraries.cartesian || document.querySelector("link[data-plotly-prefetch]")) return;
  const link = document.createElement("link");
  link.rel = "prefetch";
  link.as = "script";
  link.href = PLOTLY_SRC.cartesian;
  link.dataset.plotlyPrefetch = "";
  document.head.append(link);
}

/**
 * Load Plotly once: the cartesian bundle, or the full one where `threeD` (or where it is loaded already).
 * @param {{threeD?: boolean}} [options]
 * @returns {Promise<PlotlyLibrary>}
 */
export function loadPlotly({ threeD = false } = {}) {
  if (threeD) return loadBundle("full");
  return libraries.full && !libraries.cartesian ? libraries.full : loadBundle("cartesian");
}

/**
 * @param {ChartDiv} div
 * @param {Trace[]} traces
 * @param {object} layout
 * @param {object} config
 */
function drawNow(div, traces, layout, config) {
  const threeD = traces.some((t) => t.type === "scatter3d");
  return loadPlotly({ threeD }).then((lib) => {
    if (div.__plotly && div.__plotly !== lib) div.__plotly.purge(div); // drawn before by the other bundle
    div.__plotly = lib;
    return lib.react(div, traces, layout, config);
  });
}

// Charts below the fold are drawn when scrolled near (within NEAR_PX), but for a page's first charts
// (data-chart-eager): a ride page's twelve charts would otherwise all be laid out before any is shown.
// The latest data asked for wins. Charts of a page left before they were drawn are let go.
const NEAR_PX = 300;
/** @type {IntersectionObserver | null} */
let observer = null;
/** @type {Set<ChartDiv>} */
const pendingDivs = new Set();

/** @param {ChartDiv} div */
function forget(div) {
  delete div.__pendingChart;
  pendingDivs.delete(div);
  observer?.unobserve(div);
}

/** @param {HTMLElement} div */
function nearView(div) {
  const box = div.getBoundingClientRect();
  return box.top < window.innerHeight + NEAR_PX && box.bottom > -NEAR_PX;
}

/** @param {ChartDiv} div */
function drawPending(div) {
  const pending = div.__pendingChart;
  if (!pending) return;
  forget(div);
  drawNow(div, ...pending.args).then((drawn) => pending.waiters.forEach((w) => w.resolve(drawn)),
    (error) => pending.waiters.forEach((w) => w.reject(error)));
}

/**
 * @param {ChartDiv} div
 * @param {PendingChart["args"]} args
 * @returns {Promise<HTMLElement>}
 */
function later(div, args) {
  const watcher = observer ?? new IntersectionObserver((entries) => entries.forEach((entry) => {
    if (entry.isIntersecting) drawPending(/** @type {ChartDiv} */ (entry.target));
  }), { rootMargin: `${NEAR_PX}px 0px` });
  observer = watcher;
  for (const old of pendingDivs) if (!old.isConnected) forget(old); // the page was left
  return new Promise((resolve, reject) => {
    const waiters = div.__pendingChart?.waiters ?? [];
    waiters.push({ resolve, reject });
    div.__pendingChart = { args, waiters };
    pendingDivs.add(div);
    watcher.observe(div);
  });
}

/**
 * `Plotly.react` with the bundle that can draw `traces`, now when the chart is on or near the screen,
 * else when it is scrolled near: resolves to the chart's div, as Plotly.react does.
 * @param {ChartDiv} div
 * @param {Trace[]} traces
 * @param {object} layout
 * @param {object} config
 * @returns {Promise<HTMLElement>}
 */
export function react(div, traces, layout, config) {
  // data-chart-eager: the page's first charts, drawn at once even when the text above pushes them down
  const eager = div.hasAttribute("data-chart-eager");
  if (div.__pendingChart || (!eager && typeof IntersectionObserver === "function" && !nearView(div))) {
    return later(div, [traces, layout, config]);
  }
  return drawNow(div, traces, layout, config);
}

function plotly() {
  return {
    react,
    /** @param {ChartDiv} div */
    purge(div) {
      if (div.__pendingChart) { // never drawn: its waiters see the empty chart instead
        div.__pendingChart.waiters.forEach((w) => w.resolve(div));
        forget(div);
      }
      if (div.__plotly) div.__plotly.purge(div); // nothing to purge before Plotly drew anything
      delete div.__plotly;
    },
  };
}

/**
 * @param {string} title
 * @param {string} xTitle
 * @param {string} yTitle
 * @param {Record<string, unknown>} [extra]
 * @returns {Layout}
 */
function baseLayout(title, xTitle, yTitle, extra = {}) {
  return {
    title: { text: title, x: 0, xanchor: "left", font: { size: 14 } },
    font: FONT,
    margin: { l: 64, r: 16, t: 40, b: 48 },
    paper_bgcolor: "rgba(0,0,0,0)",
    plot_bgcolor: "#ffffff",
    xaxis: { title: { text: xTitle }, zeroline: false, gridcolor: "#e6e9ee", automargin: true },
    yaxis: { title: { text: yTitle }, zeroline: true, zerolinecolor: "#c9ced6", gridcolor: "#e6e9ee", automargin: true },
    legend: { orientation: "h", x: 1, xanchor: "right", y: 1.02, yanchor: "bottom" },
    hovermode: "x unified",
    ...extra,
  };
}

/**
 * Column `i` of rows of numbers (null where a row lacks it).
 * @param {unknown[] | null | undefined} rows
 * @param {number} i
 * @returns {(number | null)[]}
 */
function column(rows, i) {
  return (rows || []).map((row) => (Array.isArray(row) && row[i] !== null && row[i] !== undefined ? row[i] : null));
}

/**
 * Draw a message instead of a chart (no data).
 * @param {HTMLElement} div
 * @param {string} message
 */
export function emptyChart(div, message) {
  plotly().purge(div);
  div.replaceChildren();
  div.classList.add("chart-empty");
  div.textContent = message;
}

/** @param {HTMLElement} div */
function ready(div) {
  if (div.classList.contains("chart-empty")) {
    div.classList.remove("chart-empty");
    div.textContent = "";
  }
}

/**
 * x, y, z of an (N, 3) series against t_s.
 * @param {HTMLElement} div
 * @param {number[] | null | undefined} tS  times (s), shape (N,)
 * @param {unknown[] | null | undefined} xyz  shape (N, 3)
 * @param {{title: string, unit: string, scale?: number}} words
 */
export function xyzChart(div, tS, xyz, { title, unit, scale = 1 }) {
  if (!tS?.length || !xyz?.length) return emptyChart(div, `${title}: no data in this result.`);
  ready(div);
  const traces = ["x", "y", "z"].map((axis, i) => ({
    type: "scatter",
    mode: "lines",
    name: axis,
    x: tS,
    y: column(xyz, i).map((v) => (v === null ? null : v * scale)),
    line: { color: AXIS_COLOURS[axis], width: 2 },
    hovertemplate: `%{y:.4g} ${unit}`,
  }));
  return plotly().react(div, traces, baseLayout(title, "time (s)", unit), CONFIG);
}

/**
 * The six ω versions (component `component`) with the singularity index on a second axis.
 * @param {HTMLElement} div
 * @param {number[] | null | undefined} tS  shape (N,)
 * @param {(number | null)[][][]} versions  shape (N, 6, 3)
 * @param {(number | null)[] | null | undefined} singularity  shape (N,)
 * @param {{names?: string[], component?: number, omega?: unknown[] | null, excluded?: boolean[][] | null}} options
 *   excluded: shape (N, 6), samples to leave out
 */
export function versionsChart(div, tS, versions, singularity, { names, component = 1, omega = null, excluded = null }) {
  if (!tS?.length || !versions?.length) {
    return emptyChart(div, "This result has no per-version angular velocities.");
  }
  ready(div);
  const axisName = "xyz"[component];
  const nVersions = Array.isArray(versions[0]) ? versions[0].length : 0;
  /** @type {Trace[]} */
  const traces = [];
  for (let v = 0; v < nVersions; v += 1) {
    traces.push({
      type: "scatter", mode: "lines", name: `\u03c9<sup>${names?.[v] ?? v + 1}</sup>`, x: tS,
      // Excluded samples (poor conditioning, eq. 6.35) are left as gaps unless asked for.
      y: versions.map((frame, i) => {
        const value = frame?.[v]?.[component];
        return Number.isFinite(value) && !excluded?.[i]?.[v] ? value : null;
      }),
      line: { color: VERSION_COLOURS[v % VERSION_COLOURS.length], width: 1.3 },
      hovertemplate: "%{y:.3g} rad/s",
    });
  }
  if (omega?.length) {
    traces.push({ type: "scatter", mode: "lines", name: `\u03c9 (result)`, x: tS, y: column(omega, component),
                  line: { color: "#1d2630", width: 2.5, dash: "dot" }, hovertemplate: "%{y:.3g} rad/s" });
  }
  if (singularity?.length) {
    traces.push({ type: "scatter", mode: "lines", name: "singularity index |n\u00b7\u03c9\u0302|", x: tS,
                  y: singularity, yaxis: "y2", line: { color: "#7c3aed", width: 2 },
                  fill: "tozeroy", fillcolor: "rgba(124,58,237,0.08)", hovertemplate: "%{y:.2f}" });
  }
  const layout = baseLayout(`Six versions of \u03c9${axisName} and the singularity index`, "time (s)",
                            `\u03c9${axisName} (rad/s)`, {
    yaxis2: { title: { text: "singularity index" }, overlaying: "y", side: "right", range: [0, 1.05],
              showgrid: false, zeroline: false },
  });
  layout.margin.r = 64;
  layout.margin.b = 90;
  layout.legend = { orientation: "h", x: 0, xanchor: "left", y: -0.22, yanchor: "top" };
  return plotly().react(div, traces, layout, CONFIG);
}

const PAIR_COLOURS = ["#1f5fa8", "#c2410c"];

/**
 * Two rides' saddle-point paths (travel and mean removed) and their mean strides, overlaid in 3-D.
 * @param {HTMLElement} div
 * @param {number[][][] | null | undefined} pathsMm  two paths, each shape (M, 3), mm
 * @param {{first_mm: number[][], second_mm: number[][]}|null} strides  mean strides, shape (n, 3) each
 * @param {string[]} names  the two rides' names
 */
export function pairPaths3d(div, pathsMm, strides, names) {
  if (!pathsMm?.length) return emptyChart(div, "These results have no saddle-point track.");
  ready(div);
  /**
   * @param {number[][]} xyz
   * @param {number} i
   * @param {{closed?: boolean, width?: number, opacity?: number, suffix?: string}} [style]
   */
  const line = (xyz, i, { closed = false, width = 2, opacity = 1, suffix = "" } = {}) => {
    const rows = closed && xyz.length ? [...xyz, xyz[0]] : xyz;
    return {
      type: "scatter3d", mode: "lines", name: `${names[i]}${suffix}`, opacity,
      x: column(rows, 0), y: column(rows, 2), z: column(rows, 1).map((v) => (v === null ? null : -v)),
      line: { color: PAIR_COLOURS[i], width },
      hovertemplate: "x %{x:.1f} mm, z %{y:.1f} mm, height %{z:.1f} mm<extra></extra>",
    };
  };
  const traces = pathsMm.map((xyz, i) => line(xyz, i, { width: 1.5, opacity: strides ? 0.35 : 1, suffix: ", window" }));
  if (strides) {
    traces.push(line(strides.first_mm, 0, { closed: true, width: 6, suffix: ", stride" }));
    traces.push(line(strides.second_mm, 1, { closed: true, width: 6, suffix: ", stride aligned" }));
  }
  const axis = (/** @type {string} */ title) => ({ title: { text: title }, gridcolor: "#e6e9ee", zerolinecolor: "#c9ced6" });
  const layout = {
    font: FONT, paper_bgcolor: "rgba(0,0,0,0)", margin: { l: 0, r: 0, t: 8, b: 0 },
    legend: { orientation: "h", x: 0, y: 0, yanchor: "top" },
    scene: { xaxis: axis("travel x (mm)"), yaxis: axis("sideways z (mm)"), zaxis: axis("height −y (mm)"),
             aspectmode: "data", camera: { eye: { x: 1.5, y: -1.5, z: 0.9 } } },
  };
  return plotly().react(div, traces, layout, CONFIG);
}

/**
 * The vertical position of both mean strides over stride phase: the second before and after the
 * phase shift that lines it up with the first.
 * @param {HTMLElement} div
 * @param {import("./api-types").StridesView | null | undefined} strides
 * @param {string[]} names the two rides' names
 */
export function strideAlignmentChart(div, strides, names) {
  if (!strides) return emptyChart(div, "A ride is shorter than one whole stride: no mean stride to align.");
  ready(div);
  const height = (/** @type {number[][]} */ xyz) => column(xyz, 1).map((v) => (v === null ? null : -v));
  const traces = [
    { type: "scatter", mode: "lines", name: names[0], x: strides.phase, y: height(strides.first_mm),
      line: { color: PAIR_COLOURS[0], width: 2.5 } },
    { type: "scatter", mode: "lines", name: `${names[1]}, aligned`, x: strides.phase, y: height(strides.second_mm),
      line: { color: PAIR_COLOURS[1], width: 2.5 } },
    { type: "scatter", mode: "lines", name: `${names[1]}, as recorded`, x: strides.phase,
      y: height(strides.second_unaligned_mm), line: { color: PAIR_COLOURS[1], width: 1.2, dash: "dot" } },
  ];
  const layout = baseLayout("Height of S over one stride", "stride phase", "height −y (mm)");
  layout.legend = { orientation: "h", x: 0, xanchor: "left", y: -0.25, yanchor: "top" };
  layout.margin.b = 96;
  return plotly().react(div, traces, layout, CONFIG);
}

/**
 * Where two rides differ: a heat strip of the RMS distance (mm) per track and per stretch of the stride.
 * @param {HTMLElement} div
 * @param {import("./api-types").Differences | null | undefined} differences  the pair answer's `differences`
 */
export function differencesStrip(div, differences) {
  if (!differences?.per_marker?.length) return emptyChart(div, "The rides could not be compared: no differences.");
  ready(div);
  const n = differences.stretches;
  const x = Array.from({ length: n }, (_, k) => `${Math.round((k / n) * 100)}-${Math.round(((k + 1) / n) * 100)} %`);
  const y = differences.per_marker.map((m) => m.marker);
  const traces = [{
    type: "heatmap", x, y, z: differences.per_marker.map((m) => m.per_stretch_mm), zmin: 0,
    colorscale: "YlOrRd", reversescale: true, colorbar: { title: { text: "mm" }, thickness: 12 }, // dark = far apart
    hovertemplate: "%{y}, %{x} of the stride: %{z:.1f} mm<extra></extra>",
  }];
  const layout = baseLayout("Distance per track and stretch of the stride", "stride phase", "");
  layout.hovermode = "closest";
  layout.height = 150 + 36 * y.length;
  layout.yaxis = { ...layout.yaxis, zeroline: false, autorange: "reversed" };
  div.style.height = `${layout.height}px`; // one row per track, not a chart's usual height
  return plotly().react(div, traces, layout, CONFIG);
}

// ----------------------------------------------------------------------------- ride page (fits, 3-D, vibration)

// WebGL lines only where SVG gets slow: thousands of points per trace.
/** @param {number} n */
function lineType(n) {
  return n > 3000 ? "scattergl" : "scatter";
}

/**
 * Marker tracks and the saddle point S in 3-D, equal aspect (metres in the motion frame).
 * Plotted as x less S's steady travel, sideways z and height −y so "up" is up on the screen.
 * @param {HTMLElement} div
 * @param {number[] | null | undefined} tS  shape (N,), s
 * @param {((number | null)[] | null)[][] | null | undefined} markers  shape (N, M, 3), m
 * @param {unknown[] | null | undefined} saddle  shape (N, 3), m
 * @param {{names?: string[]}} [options]
 */
export function tracks3dChart(div, tS, markers, saddle, { names = ["M1", "M2", "M3"] } = {}) {
  if (!saddle?.length) return emptyChart(div, "This result has no saddle-point track.");
  ready(div);
  const colours = ["#1f5fa8", "#2f855a", "#7c3aed"];
  // S's steady travel (least-squares line of its x over time) is taken out of every track: at equal
  // scale metres of travel would flatten the centimetres of motion into a line.
  const xs = column(saddle, 0);
  const ok = /** @type {[number, number][]} */ ((tS || []).map((t, i) => [t, xs[i]])
    .filter(([t, x]) => Number.isFinite(t) && Number.isFinite(x)));
  const tMean = ok.reduce((a, [t]) => a + t, 0) / (ok.length || 1);
  const xMean = ok.reduce((a, [, x]) => a + x, 0) / (ok.length || 1);
  const slope = ok.reduce((a, [t, x]) => a + (t - tMean) * (x - xMean), 0)
    / (ok.reduce((a, [t]) => a + (t - tMean) ** 2, 0) || 1);
  const travel = (/** @type {number} */ i) => (tS && Number.isFinite(tS[i]) ? xMean + slope * (tS[i] - tMean) : 0);
  /**
   * @param {unknown[]} rows
   * @param {string} name
   * @param {string} colour
   * @param {number} width
   */
  const trace = (rows, name, colour, width) => ({
    type: "scatter3d", mode: "lines", name, x: column(rows, 0).map((v, i) => (v === null ? null : v - travel(i))),
    y: column(rows, 2), z: column(rows, 1).map((v) => (v === null ? null : -v)), line: { color: colour, width },
    hovertemplate: `${name}: x %{x:.3f} m, z %{y:.3f} m, height %{z:.3f} m<extra></extra>`,
  });
  /** @type {Trace[]} */
  const traces = [];
  const nMarkers = markers && Array.isArray(markers[0]) ? markers[0].length : 0;
  for (let m = 0; m < nMarkers && markers; m += 1) {
    traces.push(trace(markers.map((frame) => frame?.[m] ?? [null, null, null]), names[m] ?? `M${m + 1}`,
      colours[m % colours.length], 3));
  }
  traces.push(trace(saddle, "saddle point S", "#c2410c", 6));
  const axis = (/** @type {string} */ title) => ({ title: { text: title }, gridcolor: "#e6e9ee", zerolinecolor: "#c9ced6" });
  const layout = {
    font: FONT, paper_bgcolor: "rgba(0,0,0,0)", margin: { l: 0, r: 0, t: 8, b: 0 },
    legend: { orientation: "h", x: 0, y: 1, yanchor: "bottom" },
    scene: { xaxis: axis("x − steady travel (m)"), yaxis: axis("sideways z (m)"), zaxis: axis("height −y (m)"),
             aspectmode: "data", camera: { eye: { x: 1.9, y: -2.7, z: 1.2 } } },  // far enough that S stays in view
  };
  return plotly().react(div, traces, layout, CONFIG);
}

/**
 * One axis of S: the measured samples, the fitted curve over them and, below, the residual.
 * @param {HTMLElement} div
 * @param {number[] | null | undefined} tS  shape (N,)
 * @param {(number | null)[] | null} measured  shape (N,)
 * @param {(number | null)[]} fitted  shape (N,)
 * @param {(number | null)[] | null} residual  shape (N,)
 * @param {{title: string, unit: string, colour?: string}} words
 */
export function fitChart(div, tS, measured, fitted, residual, { title, unit, colour = "#1f5fa8" }) {
  if (!tS?.length || !fitted?.length) return emptyChart(div, `${title}: no data in this result.`);
  ready(div);
  const type = lineType(tS.length);
  /** @type {Trace[]} */
  const traces = [];
  if (measured?.length) {
    traces.push({ type, mode: "markers", name: "measured", x: tS, y: measured,
                  marker: { color: "#9aa3ae", size: 4 }, hovertemplate: `%{y:.4g} ${unit}` });
  }
  traces.push({ type, mode: "lines", name: "fitted", x: tS, y: fitted, line: { color: colour, width: 2.2 },
                hovertemplate: `%{y:.4g} ${unit}` });
  if (residual?.length) {
    traces.push({ type, mode: "lines", name: "residual", x: tS, y: residual, xaxis: "x", yaxis: "y2",
                  line: { color: "#c2410c", width: 1.2 }, hovertemplate: `%{y:.3g} ${unit}` });
  }
  const layout = baseLayout(title, "time (s)", unit, {
    yaxis: { title: { text: unit }, domain: residual?.length ? [0.36, 1] : [0, 1], gridcolor: "#e6e9ee",
             automargin: true, zeroline: false },
    yaxis2: { title: { text: "residual" }, domain: [0, 0.26], gridcolor: "#e6e9ee", automargin: true,
              zeroline: true, zerolinecolor: "#c9ced6" },
  });
  // one time axis under the residual panel; the legend under the chart, clear of the title
  if (residual?.length) layout.xaxis.anchor = "y2";
  layout.legend = { orientation: "h", x: 0, xanchor: "left", y: -0.2, yanchor: "top" };
  layout.margin.b = 80;
  return plotly().react(div, traces, layout, CONFIG);
}

/**
 * The vertical acceleration of S over time: unweighted and weighted with W_b and W_k.
 * @param {HTMLElement} div
 * @param {number[] | null | undefined} tS  shape (N,)
 * @param {unknown[] | null | undefined} unweighted  shape (N,), m/s²
 * @param {unknown[] | null | undefined} wb  shape (N,), m/s²
 * @param {unknown[] | null | undefined} wk  shape (N,), m/s²
 */
export function weightedChart(div, tS, unweighted, wb, wk) {
  if (!tS?.length || !wb?.length) return emptyChart(div, "This result has no vertical acceleration to weight.");
  ready(div);
  const type = lineType(tS.length);
  /**
   * @param {string} name
   * @param {unknown[]} y
   * @param {string} colour
   * @param {Record<string, unknown>} [extra]
   */
  const line = (name, y, colour, extra = {}) => ({ type, mode: "lines", name, x: tS, y,
    line: { color: colour, width: 2, ...extra }, hovertemplate: "%{y:.3g} m/s²" });
  const traces = [
    ...(unweighted?.length ? [line("unweighted", unweighted, "#9aa3ae", { dash: "dot", width: 1.5 })] : []),
    line("W_b (BS 6841)", wb, "#1f5fa8"),
    ...(wk?.length ? [line("W_k (ISO 2631-1)", wk, "#2f855a")] : []),
  ];
  const layout = baseLayout("Weighted vertical acceleration at the saddle", "time (s)", "m/s²");
  layout.legend = { orientation: "h", x: 0, xanchor: "left", y: -0.3, yanchor: "top" };
  layout.margin.b = 96;
  return plotly().react(div, traces, layout, CONFIG);
}

/**
 * Harmonic spectrum: amplitude of each harmonic k·f0, unweighted and weighted (bars).
 * @param {HTMLElement} div
 * @param {import("./api-types").SpectrumOut | null | undefined} spectrum
 */
export function spectrumChart(div, spectrum) {
  if (!spectrum?.frequency_hz?.length) return emptyChart(div, "This result has no harmonic spectrum.");
  ready(div);
  const labels = spectrum.frequency_hz.map((f, i) => `${i + 1}·f0 (${f.toFixed(2)} Hz)`);
  /**
   * @param {string} name
   * @param {(number | null)[]} y
   * @param {string} colour
   */
  const bar = (name, y, colour) => ({ type: "bar", name, x: labels, y, marker: { color: colour },
                                      hovertemplate: `%{x}: %{y:.3g} m/s²<extra>${name}</extra>` });
  const traces = [bar("unweighted", spectrum.amplitude_m_s2, "#9aa3ae"),
    bar("W_b", spectrum.amplitude_wb_m_s2, "#1f5fa8"), bar("W_k", spectrum.amplitude_wk_m_s2, "#2f855a")];
  const layout = baseLayout(`Harmonics of the stride (f0 = ${spectrum.f0_hz.toFixed(2)} Hz)`, "harmonic",
    "amplitude (m/s²)", { hovermode: "closest", barmode: "group", bargap: 0.25 });
  layout.xaxis.tickangle = -30;
  layout.legend = { orientation: "h", x: 1, xanchor: "right", y: 1.0, yanchor: "bottom" };
  layout.margin.t = 56;
  return plotly().react(div, traces, layout, CONFIG);
}
