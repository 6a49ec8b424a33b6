// Charts of the horse page, compare and grades: bars that say how many rides stand behind them, a
// trend with the horse's own normal band, and the grades scatter coloured by gait. Plotly.react only.

import { emptyChart, react } from "./charts.js";
import { GAITS, gaitLabel } from "./format.js";

/** @typedef {import("./charts.js").Trace} Trace */
/** @typedef {import("./charts.js").Layout} Layout */
/**
 * A group's bar: a mean with its spread over `n` rides (GroupStats, HorseGroupStats, LeaderboardEntry ...).
 * @typedef {{label: string, n: number, mean: number | null, std: number | null, min: number | null, max: number | null}} CountedGroup
 */
/**
 * A horse-gait point of the grades page (GET /api/grades/correlation's `points`, which the schema leaves
 * open: saddlescope.services.comparisons.analytics._described_points writes them).
 * @typedef {object} GradePoint
 * @property {string} horse
 * @property {string} gait
 * @property {number} grade the riders' average grade
 * @property {number} value the indicator's mean over the horse's rides in the gait
 * @property {string[]} [riders] who graded
 * @property {number} [rides] analysed rides behind the mean
 * @property {string | null} [first_date]
 * @property {string | null} [last_date]
 */

const FONT = { family: "system-ui, -apple-system, 'Segoe UI', Roboto, sans-serif", size: 12, color: "#1d2630" };
const CONFIG = { responsive: true, displaylogo: false, modeBarButtonsToRemove: ["lasso2d", "select2d", "autoScale2d"] };
/** @type {Record<string, string>} */
const GAIT_COLOURS = { walk: "#2f855a", sitting_trot: "#1f5fa8", rising_trot: "#7c3aed", canter: "#c2410c" };
const BAND_FILL = "rgba(47,133,90,0.16)";
const OUTSIDE = "#b91c1c";

/**
 * @param {string} title
 * @param {string} xTitle
 * @param {string} yTitle
 * @param {Record<string, unknown>} [extra]
 * @returns {Layout}
 */
function layout(title, xTitle, yTitle, extra = {}) {
  return {
    title: { text: title, x: 0, xanchor: "left", font: { size: 14 } },
    font: FONT,
    margin: { l: 56, r: 12, t: 40, b: 48 },
    paper_bgcolor: "rgba(0,0,0,0)",
    plot_bgcolor: "#ffffff",
    xaxis: { title: { text: xTitle }, gridcolor: "#e6e9ee", automargin: true },
    yaxis: { title: { text: yTitle }, gridcolor: "#e6e9ee", zerolinecolor: "#c9ced6", automargin: true },
    // Below everything, in the container's own space, so it never covers the x-axis title on a phone.
    legend: { orientation: "h", x: 0, xanchor: "left", yref: "container", y: 0, yanchor: "bottom" },
    hovermode: "closest",
    ...extra,
  };
}

/**
 * Break a long axis title into lines of at most `width` characters (Plotly does not wrap).
 * @param {string} text
 * @param {number} [width]
 */
function wrapped(text, width = 34) {
  /** @type {string[]} */
  const lines = [];
  for (const word of String(text).split(" ")) {
    const last = lines.length ? lines[lines.length - 1] : null;
    if (last !== null && `${last} ${word}`.length <= width) lines[lines.length - 1] = `${last} ${word}`;
    else lines.push(word);
  }
  return lines.join("<br>");
}

/** @param {HTMLElement} div */
function clearEmpty(div) {
  if (div.classList.contains("chart-empty")) {
    div.classList.remove("chart-empty");
    div.textContent = "";
  }
}

/**
 * Bars of the mean ± one SD per group with the number of rides written on every bar ("n = 3") and
 * in the hover; the orange range is smallest to largest ride. The legend names both.
 * @param {HTMLElement} div
 * @param {CountedGroup[]} groups
 * @param {{title: string, unit: string, xTitle: string}} words
 */
export function countedBarChart(div, groups, { title, unit, xTitle }) {
  // groups without a mean are not drawn; one with a mean has its smallest and largest ride (min, max)
  const shown = /** @type {(CountedGroup & {mean: number, min: number, max: number})[]} */ (
    (groups || []).filter((g) => Number.isFinite(g.mean)));
  if (!shown.length) return emptyChart(div, "No analysed rides to compare yet.");
  clearEmpty(div);
  const labels = shown.map((g) => g.label);
  const unitText = unit ? ` ${unit}` : "";
  const bars = {
    type: "bar", name: "mean \u00b1 SD (n = rides)", x: labels, y: shown.map((g) => g.mean),
    marker: { color: "#1f5fa8" },
    error_y: { type: "data", array: shown.map((g) => (Number.isFinite(g.std) ? g.std : 0)), visible: true,
               color: "#1d2630", thickness: 1.5, width: 6 },
    customdata: shown.map((g) => [g.n, Number.isFinite(g.std) ? g.std : null]),
    text: shown.map((g) => `n = ${g.n}`),
    textposition: "inside", insidetextanchor: "start", textfont: { color: "#ffffff", size: 12 },
    constraintext: "none", cliponaxis: false,
    hovertemplate: `%{x}: mean %{y:.4g}${unitText} \u00b1 %{customdata[1]:.3g} over %{customdata[0]} rides<extra></extra>`,
  };
  const range = {
    type: "scatter", mode: "markers", name: "smallest \u2013 largest ride", x: labels, showlegend: false,
    y: shown.map((g) => (g.min + g.max) / 2), marker: { color: "rgba(0,0,0,0)", size: 1 },
    error_y: { type: "data", symmetric: false, visible: true, color: "#c2410c", thickness: 1, width: 14,
               array: shown.map((g) => g.max - (g.min + g.max) / 2),
               arrayminus: shown.map((g) => (g.min + g.max) / 2 - g.min) },
    hoverinfo: "skip",
  };
  const yTitle = unit ? `mean (${unit})` : "mean";
  return react(div, [bars, range], layout(title, xTitle, yTitle, { bargap: 0.4, showlegend: true }), CONFIG);
}

/**
 * The page's band (the horse's own, or the club's horses' in the gait) as shapes across the whole chart,
 * so it shows even over one ride: the band shaded, its mean dashed, and each edge's 95 % interval as a
 * fainter strip (a band from few rides is itself uncertain).
 * @param {import("./api-types").PageBand | null} band
 */
function pageBandShapes(band) {
  if (!band || !Number.isFinite(band.low) || !Number.isFinite(band.high)) return [];
  /**
   * @param {number} y0
   * @param {number} y1
   * @param {string} fill
   */
  const across = (y0, y1, fill) => ({ type: "rect", xref: "paper", x0: 0, x1: 1, yref: "y", y0, y1,
    fillcolor: fill, line: { width: 0 }, layer: "below" });
  const edges = [band.low_interval_95, band.high_interval_95].filter((e) => e?.length === 2)
    .map(([a, b]) => across(a, b, "rgba(47, 133, 90, 0.10)"));
  return [
    ...edges,
    across(band.low, band.high, band.source === "club" ? "rgba(107, 114, 128, 0.20)" : "rgba(47, 133, 90, 0.22)"),
    { type: "line", xref: "paper", x0: 0, x1: 1, yref: "y", y0: band.mean, y1: band.mean, layer: "below",
      line: { color: band.source === "club" ? "#6b7280" : "#2f855a", width: 1.5, dash: "dash" } },
  ];
}

/**
 * One indicator over the rides of one gait: the values, the horse's own normal band (mean ± 2 SD of
 * the EARLIER rides, from the ride that has enough before it) as a shaded area with its mean, and the
 * rides outside their band marked in red.
 * @param {HTMLElement} div
 * @param {import("./api-types").TrendPoint[]} points
 * @param {{title: string, unit: string, gait: string, band?: import("./api-types").PageBand | null}} words
 */
export function trendChart(div, points, { title, unit, gait, band = null }) {
  const valued = /** @type {(import("./api-types").TrendPoint & {value: number})[]} */ (
    (points || []).filter((p) => Number.isFinite(p.value)));
  if (!valued.length) return emptyChart(div, `No analysed rides in ${gaitLabel(gait)} yet.`);
  clearEmpty(div);
  // Dates on a time axis when every ride has one; otherwise the rides in order as categories.
  const dated = valued.length > 1 && valued.every((p) => p.date); // one date alone: a category, not a time axis
  const x = valued.map((p, i) => (dated ? p.date : p.date || `ride ${i + 1} (#${p.ride_id})`));
  const banded = valued.map((p) => p.band);
  const bandOf = (/** @type {"low" | "high" | "mean"} */ key) => banded.map((b) => (b ? b[key] : null));
  const unitText = unit ? ` ${unit}` : "";
  /** @type {Trace[]} */
  const traces = [
    { type: "scatter", mode: "lines", name: "band low", x, y: bandOf("low"), line: { width: 0 },
      showlegend: false, hoverinfo: "skip", connectgaps: false },
    { type: "scatter", mode: "lines", name: "normal band (mean \u00b1 2 SD of earlier rides)", x, y: bandOf("high"),
      fill: "tonexty", fillcolor: BAND_FILL, line: { width: 0 }, hoverinfo: "skip", connectgaps: false },
    { type: "scatter", mode: "lines", name: "band mean", x, y: bandOf("mean"),
      line: { color: "#2f855a", width: 1.5, dash: "dash" }, hoverinfo: "skip", connectgaps: false },
    { type: "scatter", mode: "lines+markers", name: "ride", x, y: valued.map((p) => p.value),
      customdata: valued.map((p) => [p.ride_id, p.rider ?? "", p.band ? `band ${p.band.low.toPrecision(3)}\u2013${p.band.high.toPrecision(3)}` : "no band yet"]),
      line: { color: "#1f5fa8", width: 2 }, marker: { size: 8, color: "#1f5fa8" },
      hovertemplate: `%{x}: %{y:.4g}${unitText}<br>ride #%{customdata[0]}, %{customdata[1]}<br>%{customdata[2]}<extra></extra>` },
  ];
  const outside = valued.filter((p) => p.outside);
  traces.push({
    type: "scatter", mode: "markers", name: "outside its band", x: valued.map((p, i) => (p.outside ? x[i] : null)).filter((v) => v !== null),
    y: outside.map((p) => p.value), marker: { size: 14, color: "rgba(0,0,0,0)", line: { color: OUTSIDE, width: 3 } },
    hoverinfo: "skip", visible: outside.length ? true : "legendonly",
  });
  const xaxisType = dated ? "date" : "category";
  const chartLayout = layout(title, dated ? "date ridden" : "ride", unit ? `${unit}` : "", { hovermode: "closest" });
  chartLayout.xaxis.type = xaxisType;
  chartLayout.shapes = pageBandShapes(band);
  if (band) {  // the band and its edges' intervals in view even when every ride lies inside
    const ys = [...valued.map((p) => p.value), ...(band.low_interval_95 || [band.low]), ...(band.high_interval_95 || [band.high])];
    const [lo, hi] = [Math.min(...ys), Math.max(...ys)];
    const pad = (hi - lo) * 0.08 || Math.abs(hi) * 0.1 || 1;
    chartLayout.yaxis.range = [lo - pad, hi + pad];
  }
  return react(div, traces, chartLayout, CONFIG);
}

/**
 * Riders' average grade against the indicator, one point per horse and gait, one colour per gait with
 * a legend; hovering names the horse, the riders who graded and the days ridden.
 * @param {HTMLElement} div
 * @param {GradePoint[]} points
 * @param {{title: string, unit: string, label: string}} words
 */
export function gradeGaitScatter(div, points, { title, unit, label }) {
  if (!points?.length) return emptyChart(div, "No graded horses with analysed rides yet.");
  clearEmpty(div);
  const unitText = unit ? ` ${unit}` : "";
  const days = (/** @type {GradePoint} */ p) => (p.first_date ? (p.first_date === p.last_date ? p.first_date : `${p.first_date} to ${p.last_date}`) : "no dates");
  const traces = GAITS.filter((gait) => points.some((p) => p.gait === gait)).map((gait) => {
    const mine = points.filter((p) => p.gait === gait);
    return {
      type: "scatter", mode: "markers+text", name: gaitLabel(gait), x: mine.map((p) => p.value), y: mine.map((p) => p.grade),
      text: mine.map((p) => p.horse), textposition: "top center", textfont: { size: 11, color: "#1d2630" },
      customdata: mine.map((p) => [p.horse, (p.riders || []).join(", ") || "\u2013", days(p), p.rides ?? ""]),
      marker: { size: 12, color: GAIT_COLOURS[gait], line: { color: "#fff", width: 1 } },
      hovertemplate: `<b>%{customdata[0]}</b>, ${gaitLabel(gait)}<br>%{x:.4g}${unitText} over %{customdata[3]} rides, ` +
        "average grade %{y:.2f}<br>graded by %{customdata[1]}<br>ridden %{customdata[2]}<extra></extra>",
    };
  });
  const xTitle = wrapped(unit ? `${label} (${unit})` : label);
  const chartLayout = layout(title, xTitle, "riders' average grade (1\u20135)", { showlegend: true });
  chartLayout.legend.title = { text: "gait " };
  chartLayout.yaxis.range = [0.5, 5.5];
  chartLayout.yaxis.dtick = 1;
  return react(div, traces, chartLayout, CONFIG);
}
