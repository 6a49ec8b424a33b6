// One ride: its analysis job while it runs, then the result: indicator cards, exposure under the EU
// directive (with the passive-seated caveat), quality flags, kinematics charts, grade form, exports.

import { ApiError, get, itemsOf, post } from "../api.js";
import { announce, busy, fill, field, formValues, h, maybeOne, messageOf, one, page, showError } from "../dom.js";
import { emptyChart, loadPlotly, versionsChart, xyzChart } from "../charts.js";
import { glossaryLabel } from "../glossary.js";
import {
  caveatText, distanceText, durationText, fmt, gaitLabel, indicatorInfoOf, labelFragment, prettyUnit,
  rangeText,
} from "../format.js";
import { fillOptions } from "../options.js";
import { poll } from "../poll.js";
import { can } from "../session.js";
import { shareControl } from "../share.js";
import { drawAnalysis, showQuality } from "./ride-analysis.js";
import { mountAlikePanel } from "./similar.js";
import { mountReadiness } from "../ride-readiness.js";
import { mountRideEdit } from "../ride-edit.js";
import { badgeFor, hasOwnCalibration, newestJob, showJob, useRideCalibrationButton } from "../ride-job.js";
import { navigate, render } from "../router.js";

/** @typedef {import("../api-types").RideDetail} RideDetail */
/** @typedef {import("../api-types").ResultOut} ResultOut */
/** @typedef {import("../api-types").JobOut} JobOut */

// What this page reads of the parts of a result the API's schema leaves open (dicts of the pipeline,
// saddlescope.core.pipeline.result): named here, each optional, as the page guards them.
/**
 * ResultOut.quality.
 * @typedef {object} Quality
 * @property {{too_uncertain?: boolean, reason?: string}} [decision]
 * @property {boolean} [calibration_ok]
 * @property {string} [gravity_source]
 * @property {{motion?: {reprojection_error_px_median?: number | null}}} [tracks]
 * @property {{median?: number | null}} [rigidity_residual_mm]
 * @property {number | null} [singularity_index_median]
 */
/**
 * One curve fit of ResultOut.fits[axis] (core.pipeline.result._fit_summary): a straight line or a Fourier
 * series, its goodness of fit and its coefficients' 95 % intervals.
 * @typedef {object} Fit
 * @property {"LinearFit" | string} kind
 * @property {number} [order]
 * @property {number} [r2]
 * @property {number} [adj_r2]
 * @property {number} [rmse]
 * @property {number} [noise_lag1]
 * @property {number} [omega_rad_s]
 * @property {number} [slope]
 * @property {number[]} [trend]
 * @property {{omega_rad_s?: number[], slope?: number[], trend?: number[][]}} [ci95]
 */
/**
 * What this page reads of a ride's full result document (GET /api/rides/{id}/export/json, no model in the
 * API: saddlescope.services.results.documents): the six ω versions the compact result leaves out.
 * @typedef {object} FullDocument
 * @property {{omega_versions_rad_s?: (number | null)[][][], omega_versions_excluded?: boolean[][],
 *   singularity_index_per_frame?: (number | null)[], omega_rad_s?: unknown[]}} [angular]
 * @property {{t_s?: number[]}} [saddle]
 */
/** @typedef {{key: string, title: string, note: string}} Card an indicator's card */

// Order of saddlescope.core.kinematics.VERSION_NAMES (eq. 6.3-6.4 for each reference marker).
const VERSION_NAMES = ["1,ver1", "2,ver1", "1,ver2", "2,ver2", "1,ver3", "2,ver3"];

/** @type {Card[]} */
const MAIN_CARDS = [
  { key: "acc_y_wb_rms", title: "W_b r.m.s.", note: "BS 6841" },
  { key: "acc_y_wk_rms", title: "W_k r.m.s.", note: "ISO 2631-1" },
  { key: "vdv_y_wb", title: "VDV W_b", note: "vibration dose value" },
  { key: "vdv_y_wk", title: "VDV W_k", note: "vibration dose value" },
  { key: "crest_factor_y", title: "Crest factor", note: "W_b peak / r.m.s." },
  { key: "acc_y_max", title: "Peak acceleration", note: "unweighted, vertical" },
];
/** @type {Card[]} */
const RIDE_CARDS = [
  { key: "vel_x_avg_kmh", title: "Speed", note: "average, direction of travel" },
  { key: "amplitude_y_m", title: "Vertical amplitude", note: "peak-to-peak at the saddle" },
  { key: "stride_frequency_hz", title: "Stride frequency", note: "" },
  { key: "duration_s", title: "Analysed window", note: "whole strides" },
];
const THRESHOLDS = [
  { basis: "a8", level: "action", label: "A(8) action value", value: "0.5 m/s\u00b2" },
  { basis: "a8", level: "limit", label: "A(8) limit value", value: "1.15 m/s\u00b2" },
  { basis: "vdv", level: "action", label: "VDV action value", value: "9.1 m/s\u00b9\u00b7\u2077\u2075" },
  { basis: "vdv", level: "limit", label: "VDV limit value", value: "21 m/s\u00b9\u00b7\u2077\u2075" },
];
const EXPORTS = [
  { fmt: "csv", text: "Indicators (CSV)" },
  { fmt: "xlsx", text: "Indicators (Excel .xlsx)" },
  { fmt: "json", text: "Full result (JSON)" },
  { fmt: "c3d", text: "3-D tracks (C3D)" },
  { fmt: "trc", text: "3-D tracks (TRC)" },
];

/**
 * @param {ResultOut} result
 * @param {string} key
 */
function unitOf(result, key) {
  return result.units?.[key] ?? indicatorInfoOf(key).unit;
}

/**
 * @param {ResultOut} result
 * @param {Card} card
 */
function card(result, { key, title, note }) {
  const value = result.indicators?.[key];
  const unit = unitOf(result, key);
  const titleEl = h("h3", { class: "card-title", id: `card-${key}` }, labelFragment(title));
  return h("article", { class: "card", dataset: { indicator: key }, "aria-labelledby": `card-${key}`,
                        title: indicatorInfoOf(key).label.replaceAll("_", "") },
    titleEl,
    h("p", { class: "card-value" },
      h("span", { "data-value": value ?? "" }, fmt(value)),
      unit ? h("span", { class: "card-unit" }, ` ${prettyUnit(unit)}`) : null),
    intervalText(result, key) ? h("p", { class: "card-note card-ci", dataset: { ci: key } },
      // as the fits' intervals were shown: "95 % interval 14.1–14.3 km/h"
      `95 % interval ${String(intervalText(result, key)).slice("95 %: ".length)}${unit ? ` ${prettyUnit(unit)}` : ""}`) : null,
    note ? h("p", { class: "card-note" }, labelFragment(note)) : null);
}

// "95 %: 1.10–1.41" from the result's indicators_interval_95 (issue 27), or null without one; never
// "18.0–18.0" (format.js rangeText).
/**
 * @param {ResultOut} result
 * @param {string} key
 * @param {number} [digits]
 */
function intervalText(result, key, digits) {
  const pair = result.indicators_interval_95?.[key];
  if (!Array.isArray(pair)) return null;
  return `95 %: ${rangeText(pair[0], pair[1], digits)}`;
}

// A ride too uncertain for a decision says so above its numbers (docs/accuracy.md).
/** @param {ResultOut} result */
function decisionNote(result) {
  const decision = /** @type {Quality | undefined} */ (result.quality)?.decision;
  if (!decision?.too_uncertain) return null;
  return h("p", { class: "decision-uncertain", role: "note", dataset: { decision: "too-uncertain" } },
    h("strong", {}, "Too uncertain for a decision: "),
    `${decision.reason}. Do not compare or rank this ride; leaderboards leave it out.`);
}

/** @param {ResultOut} result */
function exposureRows(result) {
  const ind = result.indicators || {};
  return THRESHOLDS.map(({ basis, level, label, value }) => h("tr", { dataset: { threshold: `${basis}_${level}` } },
    h("th", { scope: "row" }, label, h("span", { class: "hint" }, ` (${value})`)),
    ...["wb", "wk"].map((w) => h("td", { class: "num", dataset: { key: `t_${basis}_${level}_${w}_h` },
                                         "data-value": ind[`t_${basis}_${level}_${w}_h`] ?? "" },
      durationText(ind[`t_${basis}_${level}_${w}_h`]), timeInterval(result, `t_${basis}_${level}_${w}_h`))),
    ...["wb", "wk"].map((w) => h("td", { class: "num", dataset: { key: `d_${basis}_${level}_${w}_km` } },
      distanceText(ind[`d_${basis}_${level}_${w}_km`]), distanceInterval(result, `d_${basis}_${level}_${w}_km`)))));
}

/**
 * @param {ResultOut} result
 * @param {string} key
 */
function timeInterval(result, key) {
  const pair = result.indicators_interval_95?.[key];
  if (!Array.isArray(pair)) return null;
  const end = (/** @type {number | null | undefined} */ v) => (v === null || v === undefined ? "∞" : durationText(v));
  if (end(pair[0]) === end(pair[1])) return null; // "1 min–1 min" says nothing the value does not
  return h("span", { class: "ci-small", dataset: { ci: key } }, ` (95 %: ${end(pair[0])}–${end(pair[1])})`);
}

/**
 * @param {ResultOut} result
 * @param {string} key
 */
function distanceInterval(result, key) {
  const pair = result.indicators_interval_95?.[key];
  if (!Array.isArray(pair)) return null;
  const end = (/** @type {number | null | undefined} */ v) => (v === null || v === undefined ? "∞" : distanceText(v));
  if (end(pair[0]) === end(pair[1])) return null; // "about 4 m–about 4 m" says nothing the value does not
  return h("span", { class: "ci-small", dataset: { ci: key } }, ` (95 %: ${end(pair[0])}–${end(pair[1])})`);
}

/** @param {ResultOut} result */
function qualityFacts(result) {
  /** @type {Quality} */
  const q = result.quality || {};
  /** @type {{board_square_error_mm?: number}} ResultOut.calibration_checks, which the schema leaves open */
  const checks = result.calibration_checks || {};
  /** @type {[string, string | null][]} */
  const facts = [
    ["Calibration", q.calibration_ok === undefined ? null : q.calibration_ok ? "ok" : "see warnings"],
    ["Board square error", checks.board_square_error_mm === undefined ? null : `${fmt(checks.board_square_error_mm)} mm`],
    ["Gravity from", q.gravity_source ? glossaryLabel("gravity_source", q.gravity_source) : null],
    ["Reprojection error (median)", q.tracks?.motion?.reprojection_error_px_median == null ? null
      : `${fmt(q.tracks?.motion?.reprojection_error_px_median)} px`],
    ["Rigidity residual (median)", q.rigidity_residual_mm?.median == null ? null : `${fmt(q.rigidity_residual_mm?.median)} mm`],
    ["Singularity index (median)", q.singularity_index_median == null ? null : fmt(q.singularity_index_median, 2)],
    ["Stride period", result.period_s == null ? null : `${fmt(result.period_s)} s`],
  ];
  return facts.filter(([, value]) => value !== null && value !== undefined)
    .flatMap(([term, value]) => [h("dt", {}, term), h("dd", {}, String(value))]);
}

const MARKER_NAMES = ["M1", "M2", "M3"];

/** @typedef {Record<string, Fit[]>} Fits ResultOut.fits: per axis x, y, z, one fit per marker */
/** @typedef {[number, number, number]} ValueInterval a value and its 95 % interval's ends */

/**
 * The mean of the finite values; null when none is.
 * @param {(number | null | undefined)[]} values
 */
function mean(values) {
  const ok = /** @type {number[]} */ (values.filter(Number.isFinite));
  return ok.length ? ok.reduce((a, b) => a + b, 0) / ok.length : null;
}

// The stride frequency and the average speed with their 95 % intervals, from the curve fits (thesis
// 5.5): the markers share one fundamental; the speed is the mean slope of their x fits.
/**
 * @param {Fits} fits
 * @returns {{stride?: ValueInterval, speed?: ValueInterval}} in Hz and m/s
 */
function fitIntervals(fits) {
  /** @type {{stride?: ValueInterval, speed?: ValueInterval}} */
  const out = {};
  const y = (fits.y || []).find((f) => Array.isArray(f.ci95?.omega_rad_s));
  if (y && y.omega_rad_s !== undefined && Number.isFinite(y.omega_rad_s)) {
    const [lo, hi] = (y.ci95?.omega_rad_s ?? []).map((w) => w / (2 * Math.PI));
    out.stride = [y.omega_rad_s / (2 * Math.PI), lo, hi];
  }
  /** @type {[number | undefined, number[] | undefined][]} each marker's speed and its interval */
  const speeds = (fits.x || []).map((f) => (f.kind === "LinearFit"
    ? [f.slope, f.ci95?.slope] : [f.trend?.[0], f.ci95?.trend?.[0]]));
  const speed = mean(speeds.map(([v]) => v));
  const lo = mean(speeds.map(([, ci]) => ci?.[0]));
  const hi = mean(speeds.map(([, ci]) => ci?.[1]));
  if (speed !== null && lo !== null && hi !== null) out.speed = [speed, lo, hi];
  return out;
}

/** @param {Fits} fits */
function fitFacts(fits) {
  const { stride, speed } = fitIntervals(fits);
  /** @type {[string, string][]} */
  const facts = [];
  if (stride) {
    facts.push(["Stride frequency (95 % CI)",
      `${fmt(stride[0], 4)} Hz (${rangeText(stride[1], stride[2], 4)})`]);
  }
  if (speed) {
    // km/h as on the speed card: one unit per quantity on a page (the fits give m/s)
    const kmh = speed.map((v) => v * 3.6);
    facts.push(["Average speed (95 % CI)", `${fmt(kmh[0], 3)} km/h (${rangeText(kmh[1], kmh[2], 3)})`]);
  }
  return facts.flatMap(([term, value]) => [h("dt", {}, term), h("dd", {}, value)]);
}

// The 95 % intervals under the cards of the indicators that have one (speed in km/h, stride in Hz).
/**
 * @param {HTMLElement} view
 * @param {Fits} fits
 */
function intervalNotes(view, fits) {
  const { stride, speed } = fitIntervals(fits);
  /** @type {(key: string, text: string) => void} */
  const put = (key, text) => {
    // a result with indicators_interval_95 already shows the interval under the card
    if (view.querySelector(`[data-ci="${key}"]`)) return;
    const cardEl = maybeOne(view, `[data-indicator="${key}"]`);
    if (cardEl) cardEl.append(h("p", { class: "card-note card-ci", dataset: { ci: key } }, text));
  };
  if (speed) put("vel_x_avg_kmh", `95 % interval ${rangeText(speed[1] * 3.6, speed[2] * 3.6)} km/h`);
  if (stride) put("stride_frequency_hz", `95 % interval ${rangeText(stride[1], stride[2], 4)} Hz`);
}

/** @param {Fits} fits */
function fitRows(fits) {
  return ["x", "y", "z"].flatMap((axis) => (fits[axis] || []).map((f, m) => h("tr", { dataset: { fit: `${axis}${m}` } },
    h("th", { scope: "row" }, `${MARKER_NAMES[m] ?? `M${m + 1}`} ${axis}`),
    h("td", {}, f.kind === "LinearFit" ? "straight line" : `Fourier, order ${Math.round(Number(f.order))}`),
    h("td", { class: "num" }, fmt(f.r2, 4)),
    h("td", { class: "num" }, fmt(f.adj_r2, 4)),
    h("td", { class: "num" }, f.rmse !== undefined && Number.isFinite(f.rmse) ? fmt(f.rmse * 1000, 2) : "\u2013"),
    h("td", { class: "num" }, fmt(f.noise_lag1, 2)))));
}

/**
 * The ω component (0, 1, 2: x, y, z) with the most motion.
 * @param {unknown[] | null | undefined} omega rows of [x, y, z]
 */
function largestComponent(omega) {
  const sums = [0, 0, 0];
  for (const row of /** @type {(number[] | null)[]} */ (omega || [])) {
    for (let i = 0; i < 3; i += 1) if (row && Number.isFinite(row[i])) sums[i] += row[i] ** 2;
  }
  return sums.indexOf(Math.max(...sums));
}

/**
 * @param {number} rideId
 * @returns {Promise<FullDocument | null>} null: the ride has no result document
 */
async function fullDocument(rideId) {
  try {
    return await get(`/api/rides/${rideId}/export/json`);
  } catch (error) {
    if (error instanceof ApiError && error.status === 404) return null;
    throw error;
  }
}

// The x, y, z charts against time, each of one series of the result (ResultSeries), in page order. A chart the
// page's markup lacks gets its figure after the one before it here, so a new series' chart is one line.
/** @type {{chart: string, series: keyof import("../api-types").ResultSeries, title: string, unit: string}[]} */
const XYZ_CHARTS = [
  { chart: "position", series: "position_m", title: "Position", unit: "m" },
  { chart: "velocity", series: "velocity_m_s", title: "Velocity", unit: "m/s" },
  { chart: "acceleration", series: "acceleration_m_s2", title: "Acceleration", unit: "m/s\u00b2" },
  { chart: "omega", series: "omega_rad_s", title: "Angular velocity \u03c9", unit: "rad/s" },
  { chart: "alpha", series: "alpha_rad_s2", title: "Angular acceleration \u03b1", unit: "rad/s\u00b2" },
];

/**
 * The chart `[data-chart=name]`, or a new figure for it after `previous`'s figure.
 * @param {HTMLElement} view
 * @param {{chart: string, title: string}} entry
 * @param {HTMLElement | null} previous
 * @returns {HTMLElement}
 */
function chartSlot(view, { chart, title }, previous) {
  const found = view.querySelector(`[data-chart="${chart}"]`);
  if (found instanceof HTMLElement) return found;
  const div = h("div", { class: "chart", dataset: { chart }, role: "figure", "aria-label": `${title} x, y, z against time` });
  const figure = previous?.closest("figure");
  if (!figure) throw new Error(`the ride page has no figure before the ${chart} chart`);
  figure.after(h("figure", {}, div));
  return div;
}

/**
 * @param {HTMLElement} view
 * @param {Partial<import("../api-types").ResultSeries>} series
 */
function drawSeries(view, series) {
  /** @type {HTMLElement | null} */
  let previous = null;
  for (const entry of XYZ_CHARTS) {
    previous = chartSlot(view, entry, previous);
    xyzChart(previous, series.t_s, series[entry.series], { title: entry.title, unit: entry.unit });
  }
}

/**
 * @param {HTMLElement} view
 * @param {number} rideId
 * @param {ResultOut} result
 */
async function drawVersions(view, rideId, result) {
  const div = one(view, '[data-chart="versions"]');
  /** @type {Partial<import("../api-types").ResultSeries>} */
  const series = result.series || {};
  let t = series.t_s;
  // the series the schema says only "list" of: shapes (N, 6, 3), (N,), (N, 3) and (N, 6)
  let versions = /** @type {(number | null)[][][] | null | undefined} */ (series.omega_versions_rad_s);
  let singularity = /** @type {(number | null)[] | null | undefined} */ (series.singularity_index_per_frame);
  let omega = series.omega_rad_s;
  let excluded = /** @type {boolean[][] | null | undefined} */ (series.omega_versions_excluded);
  if (!versions) {
    // The compact result leaves the six versions out; the full document has them.
    const doc = await fullDocument(rideId);
    versions = doc?.angular?.omega_versions_rad_s;
    excluded = doc?.angular?.omega_versions_excluded;
    singularity = doc?.angular?.singularity_index_per_frame;
    t = doc?.saddle?.t_s ?? t;
    omega = doc?.angular?.omega_rad_s ?? omega;
  }
  if (!versions?.length) {
    emptyChart(div, "This result has no per-version angular velocities (ω versions).");
    return;
  }
  const select = h("select", { id: "versions-component" },
    ...["x", "y", "z"].map((axis, i) => h("option", { value: String(i) }, `\u03c9${axis}`)));
  select.value = String(largestComponent(omega));
  const showExcluded = h("input", { type: "checkbox", id: "versions-excluded" });
  const draw = () => versionsChart(div, t, versions, singularity, {
    names: VERSION_NAMES, component: Number(select.value), omega,
    excluded: showExcluded.checked ? null : excluded });
  select.addEventListener("change", draw);
  showExcluded.addEventListener("change", draw);
  const nExcluded = (excluded || []).flat().filter(Boolean).length;
  /** @type {HTMLElement} */ (div.closest("figure")).prepend(h("div", { class: "chart-controls" },
    h("div", { class: "field inline-field" }, h("label", { for: "versions-component" }, "Component"), select),
    nExcluded ? h("div", { class: "field inline-field" }, showExcluded,
      h("label", { for: "versions-excluded" },
        `Show the ${nExcluded} samples excluded for poor conditioning (near the singularity)`)) : null));
  draw();
}

/**
 * @param {HTMLElement} view
 * @param {RideDetail} ride
 */
function attachGradeForm(view, ride) {
  const form = one(view, "[data-grade-form]", HTMLFormElement);
  const ok = one(form, "[data-form-ok]");
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    showError(form, null);
    ok.hidden = true;
    const values = formValues(form);
    try {
      await busy(form, () => post("/api/grades", {
        ride_id: ride.id, rider_id: Number(values.rider_id), grade: Number(values.grade),
        ...(values.comment ? { comment: values.comment } : {}) }));
      ok.textContent = `Grade ${values.grade} saved.`;
      ok.hidden = false;
      announce(`Grade ${values.grade} saved.`);
    } catch (error) {
      showError(form, error);
    }
  });
  return fillOptions(form).then(async () => {
    field(form, "rider_id", HTMLSelectElement).value = String(ride.rider_id);
    /** @type {import("../api-types").GradeOut[]} */
    const grades = itemsOf(await get("/api/grades", { params: { ride_id: ride.id } }));
    const own = grades.find((g) => g.rider_id === ride.rider_id);
    if (own) {
      field(form, "grade", HTMLSelectElement).value = String(own.grade);
      field(form, "comment").value = own.comment ?? "";
    }
  });
}

// A ride of several passes says how many strides each gave and how far the passes' W_b r.m.s. spread
// (issue 38: "3 passes: 2, 2 and 3 strides"); nothing for one pass.
/** @param {ResultOut} result */
function passesNote(result) {
  const passes = result.passes;
  if (!passes?.line) return null;
  const spread = passes.wb_rms_spread_percent != null && Number.isFinite(passes.wb_rms_spread_percent)
    ? `; pass-to-pass spread of the W_b r.m.s. ±${passes.wb_rms_spread_percent.toFixed(1)} %`
    : "";
  return h("p", { class: "card-note", dataset: { passes: String(passes.count) } },
    `${passes.line}, pooled into these numbers${spread}.`);
}

/**
 * @param {HTMLElement} view
 * @param {RideDetail} ride
 * @param {ResultOut} result
 */
function showResult(view, ride, result) {
  const box = one(view, "[data-result]");
  fill(one(view, "[data-indicator-cards]"),
    ...[decisionNote(result), passesNote(result)].filter(Boolean),
    h("div", { class: "card-group" }, ...MAIN_CARDS.map((c) => card(result, c))),
    h("div", { class: "card-group secondary" }, ...RIDE_CARDS.map((c) => card(result, c))));
  one(view, "[data-exposure-table] tbody").replaceChildren(...exposureRows(result));
  one(view, "[data-caveat]").textContent = caveatText();
  one(view, "[data-quality-facts]").replaceChildren(...qualityFacts(result));
  showQuality(view, result);
  /** @type {Fits} the fits' dicts, as the pipeline writes them (the schema leaves them open) */
  const fits = /** @type {Fits} */ (result.fits || {});
  const fitsPanel = one(view, "[data-fits]");
  fitsPanel.hidden = !Object.keys(fits).length;
  one(view, "[data-fit-facts]").replaceChildren(...fitFacts(fits));
  one(view, "[data-fit-table] tbody").replaceChildren(...fitRows(fits));
  one(view, "[data-exports]").replaceChildren(...EXPORTS.map((e) => h("li", {},
    h("a", { href: `/api/rides/${ride.id}/export/${e.fmt}`, download: "", dataset: { export: e.fmt } }, e.text))));
  intervalNotes(view, fits);
  for (const [hook, suffix] of [["[data-report-link]", "report"], ["[data-report-pdf]", "report.pdf"]]) {
    one(view, hook, HTMLAnchorElement).href = `/api/rides/${ride.id}/${suffix}`;
  }
  const shareSlot = one(view, "[data-share-slot]");
  if (!shareSlot.childElementCount) fill(shareSlot, shareControl({ rideId: ride.id })); // kept across refreshes
  box.hidden = false;
  drawSeries(view, result.series || {});
  drawAnalysis(view, result);
}

/**
 * The saddle, pad and rider's weight of the ride, under its details line (a saddle links to its page).
 * @param {HTMLElement} view
 * @param {RideDetail} ride
 */
async function showSaddle(view, ride) {
  if (ride.saddle_id == null && !ride.pad && ride.rider_weight_kg == null) return;
  /** @type {import("../api-types").SaddleOut | null} */
  const saddle = ride.saddle_id == null ? null : await get(`/api/saddles/${ride.saddle_id}`);
  /** @type {(string | HTMLElement)[]} */
  const parts = [];
  if (saddle) parts.push("Saddle ", h("a", { href: `#/saddles/${saddle.id}` }, saddle.name));
  if (ride.pad) parts.push(parts.length ? `, pad: ${ride.pad}` : `Pad: ${ride.pad}`);
  if (ride.rider_weight_kg != null) parts.push(`${parts.length ? " \u00b7 " : ""}rider's weight ${Number(ride.rider_weight_kg.toFixed(1))} kg`);
  maybeOne(view, "[data-ride-meta]")?.after(h("p", { class: "hint", "data-ride-saddle": true }, ...parts));
}

/**
 * @param {HTMLElement} view
 * @param {Record<string, string>} params the ride's id
 */
export async function mountRide(view, { id }) {
  loadPlotly().catch(() => {}); // parse the chart library while the API answers (a chart says if it failed)
  view.append(page("ride"));
  const rideId = Number(id);
  const state = one(view, "[data-ride-state]");
  /** @type {RideDetail} */
  let ride;
  try {
    ride = await get(`/api/rides/${rideId}`);
  } catch (error) {
    if (!state.isConnected) return undefined; // left meanwhile: `view` holds another page now
    one(view, "[data-ride-title]").textContent = `Ride #${id}`;
    state.replaceChildren(h("p", { class: "form-error", role: "alert" }, messageOf(error)));
    return undefined;
  }
  if (!state.isConnected) return undefined; // left while the ride loaded: `view` holds another page now
  const horse = ride.horse_name;
  const rider = ride.rider_name;
  one(view, "[data-ride-crumb]").textContent = `#${ride.id}`;
  one(view, "[data-ride-title]").textContent = `${horse} \u2013 ${gaitLabel(ride.gait)}`;
  document.title = `${horse}, ${gaitLabel(ride.gait)} \u2013 SaddleScope`;
  /** @type {{source?: {kind?: string, file?: string}}} RideDetail.meta (ride.json's), which the schema leaves open */
  const meta = ride.meta;
  const showMeta = () => one(view, "[data-ride-meta]").replaceChildren(
    `Ride #${ride.id} \u00b7 rider ${rider} \u00b7 ${ride.direction === "CW" ? "clockwise" : "counter-clockwise"}`,
    ride.ridden_on ? ` \u00b7 ${ride.ridden_on}` : "",
    // a motion-capture file analysed as a ride says so: no cameras, no calibration behind it
    meta?.source?.kind === "mocap" ? ` \u00b7 from the motion-capture file ${meta.source.file}` : "",
    " \u00b7 ", h("span", { class: `badge status-${ride.status}`, "data-ride-badge": "" }, ride.status));
  showMeta();
  showSaddle(view, ride).catch((error) => console.info("saddle not shown:", messageOf(error)));
  // A ride still missing clips says what it lacks (and where to add it) instead of an empty page.
  if (ride.status === "new" && meta?.source?.kind !== "mocap") {
    const slot = maybeOne(view, "[data-readiness-slot]");
    if (slot) mountReadiness(slot, rideId).catch((error) => console.info("readiness not available:", messageOf(error)));
  }

  // Details (horse, rider, gait, direction, date, notes) editable in place; re-analysis offered where a
  // change alters the result; delete for the ride's maker or an admin.
  // Folded away under one line so the results come first; open when the shown result is outdated.
  const editSlot = maybeOne(view, "[data-ride-edit-slot]");
  if (editSlot && can("ride.create")) {
    const form = h("div");
    editSlot.replaceChildren(h("details", { class: "ride-edit-box", open: Boolean(ride.result_outdated_by?.length) },
      h("summary", {}, can("ride.delete", ride.created_by) ? "Edit the ride's details or delete it"
        : "Edit the ride's details"), form));
    mountRideEdit(form, ride, {
      onSaved: () => render(),
      onDeleted: () => navigate("/rides"),
      onReanalyse: (job) => follow(job?.id), // followed live; the page is drawn again once it is done
    }).catch((error) => console.warn("ride details form failed:", messageOf(error)));
  }

  /** @type {(() => void) | null} */
  let stopAlike = null;
  async function loadResult() {
    /** @type {ResultOut} */
    const result = await get(`/api/rides/${rideId}/result`, { params: { max_points: 2000 } });
    if (!state.isConnected) return;
    state.replaceChildren();
    showResult(view, ride, result);
    stopAlike?.();
    stopAlike = mountAlikePanel(view, ride);
    await Promise.all([drawVersions(view, rideId, result), attachGradeForm(view, ride)]);
  }

  // Follow the ride's newest job live: its badge, progress and remaining time; once an analysis finishes,
  // the page is drawn again (new numbers, no "computed with the old ..." notice); once it fails, the
  // sentence naming the clip and what to do, with the way to do it.
  let hadResult = false;
  if (ride.status === "analysed" || ride.indicators) {
    try {
      await loadResult();
      hadResult = true;
    } catch (error) {
      if (!(error instanceof ApiError) || error.status !== 404) {
        state.replaceChildren(h("p", { class: "form-error", role: "alert" }, messageOf(error)));
        return undefined;
      }
    }
  }
  if (!hadResult) state.replaceChildren(h("p", {}, "This ride has not been analysed yet."));
  /** @type {number | null | undefined} */
  let followedId = ride.latest_job_id;
  let thenAnalyse = false;
  let seenUnfinished = false;
  /** @type {import("../ride-job.js").Follow} */
  const follow = (jobId, { thenAnalyse: next = false } = {}) => {
    followedId = jobId ?? followedId;
    thenAnalyse = next;
    seenUnfinished = true;
    poller.restart();
  };
  const setBadge = (/** @type {JobOut} */ job) => {
    const { status, text } = badgeFor(job, ride.status);
    const badge = maybeOne(view, "[data-ride-meta] .badge");
    if (badge) { badge.className = `badge status-${status}`; badge.textContent = text; }
  };
  // While the ride is analysed again, its "computed with the old ..." notice says so instead of offering it.
  const sayReanalysing = (/** @type {JobOut} */ job) => {
    const button = maybeOne(view, "[data-ride-edit-reanalyse]");
    if (button) button.hidden = true;
    const text = maybeOne(view, "[data-ride-edit-outdated-text]");
    if (text) {
      text.textContent = `Re-analysis ${job.status === "queued" ? "waiting to start" : "running"}: the result shown is `
        + "from the old details until it is done.";
    }
  };
  const poller = poll(async () => {
    let job;
    try {
      job = await newestJob(rideId, followedId);
    } catch (error) {
      state.replaceChildren(h("p", { class: "form-error", role: "alert" }, messageOf(error)));
      return 5000;
    }
    if (!state.isConnected) return false;
    if (!job) {
      if (!hadResult) {
        state.replaceChildren(h("p", {}, "This ride has not been analysed yet, and no analysis job exists for it."),
          h("button", { type: "button", onclick: async (event) => {
            /** @type {HTMLButtonElement} */ (event.target).disabled = true;
            try {
              follow(/** @type {JobOut | null} */ (await post(`/api/rides/${rideId}/analyze`))?.id ?? null);
            } catch (err) {
              state.append(h("p", { class: "form-error", role: "alert" }, messageOf(err)));
            }
          } }, "Analyse now"));
      }
      return false;
    }
    followedId = job.id;
    setBadge(job);
    const unfinished = job.status === "queued" || job.status === "running";
    if (job.status === "done") {
      if (job.kind === "calibrate_rig" && thenAnalyse) {
        thenAnalyse = false;
        followedId = /** @type {JobOut | null} */ (await post(`/api/rides/${rideId}/analyze`))?.id ?? null;
        return true;
      }
      if (job.kind === "analyze" && seenUnfinished) {
        announce("Analysis finished.");
        render(); // draw the page again: the new numbers, the badge, no outdated-result notice
        return false;
      }
      if (!hadResult || job.kind === "calibrate_rig") showJob(state, ride, job, { follow });
      return false;
    }
    if (unfinished) seenUnfinished = true;
    if (unfinished && job.kind === "analyze") sayReanalysing(job);
    showJob(state, ride, job, { follow });
    return unfinished;
  });
  // A ride carrying its own calibration clips (a bundle's) offers them to its rig.
  const calibrationSlot = maybeOne(view, "[data-ride-calibration-slot]");
  // (a failed ride offers them among its remedies instead)
  if (calibrationSlot && ride.status === "analysed" && ride.rig_id && hasOwnCalibration(ride) && can("ride.create")) {
    calibrationSlot.replaceChildren(h("p", { class: "hint" },
      "This ride carries its own calibration clips. If the cameras were moved since the rig was calibrated, "
      + "they can calibrate the rig again for this and later rides. "), useRideCalibrationButton(ride, follow));
  }
  return () => { poller.stop(); stopAlike?.(); };
}
