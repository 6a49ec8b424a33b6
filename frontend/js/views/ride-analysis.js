// The ride page's analysis panels: quality in plain words, 3-D tracks, fitted curves over the measured
// samples with residuals, weighted vertical acceleration and its spectrum, why a rotation reads zero.

import { AXIS_COLOURS, fitChart, spectrumChart, tracks3dChart, weightedChart } from "../charts.js";
import { h, one } from "../dom.js";

/** @typedef {import("../api-types").ResultOut} ResultOut */
/** @typedef {import("../api-types").ResultSeries} ResultSeries */
/** @typedef {import("../api-types").QualityNoteOut} QualityNoteOut */

/** @type {Record<string, string>} */
const SEVERITY_WORDS = { ok: "OK", check: "Check", problem: "Problem" };
const AXES = /** @type {const} */ (["x", "y", "z"]);
const AXIS_WORDS = { x: "x, direction of travel", y: "y, vertical (down)", z: "z, sideways" };
// ω components as riders name the rotations of the back (x travel, y down, z sideways)
const ROTATION_WORDS = ["roll (about the direction of travel)", "yaw (about the vertical)",
  "pitch (about the sideways axis)"];
/**
 * A quantity of S the fit charts show: the series of its measured samples, its fitted curve and residual.
 * @typedef {{label: string, unit: string, measured: keyof ResultSeries, fitted: keyof ResultSeries,
 *   residual: keyof ResultSeries, note: string}} Quantity
 */
/** @type {Record<string, Quantity>} */
const QUANTITIES = {
  position: { label: "Position", unit: "m", measured: "position_m", fitted: "position_fitted_m",
              residual: "position_residual_m", note: "measured: the registered samples" },
  velocity: { label: "Velocity", unit: "m/s", measured: "velocity_measured_m_s", fitted: "velocity_m_s",
              residual: "velocity_residual_m_s", note: "measured: differences of the measured positions" },
  acceleration: { label: "Acceleration", unit: "m/s\u00b2", measured: "acceleration_measured_m_s2",
                  fitted: "acceleration_m_s2", residual: "acceleration_residual_m_s2",
                  note: "measured: second differences of the measured positions" },
};

/**
 * Column `i` of rows of numbers (null where a row lacks a finite one).
 * @param {unknown[] | null | undefined} rows
 * @param {number} i
 * @returns {(number | null)[]}
 */
function column(rows, i) {
  return (rows || []).map((row) => (Array.isArray(row) && Number.isFinite(row[i]) ? row[i] : null));
}

/**
 * The quality notes: the overall line, then one sentence per flag with the expert detail folded away.
 * @param {HTMLElement} view
 * @param {ResultOut} result
 */
export function showQuality(view, result) {
  const notes = result.quality_notes || [];
  const summary = result.quality_summary || { severity: "ok", message: "" };
  const line = one(view, "[data-quality-summary]");
  line.className = `quality-summary severity-${summary.severity}`;
  line.replaceChildren(h("span", { class: `severity severity-${summary.severity}` },
    SEVERITY_WORDS[summary.severity] ?? summary.severity), " ", summary.message || "");
  // flags that ask for the same thing are one line, with each expert sentence behind its toggle
  /** @type {Map<string, QualityNoteOut & {details: string[]}>} */
  const groups = new Map();
  for (const note of notes) {
    if (!groups.has(note.message)) groups.set(note.message, { ...note, details: [] });
    groups.get(note.message)?.details.push(note.detail);
  }
  one(view, "[data-quality-notes]").replaceChildren(...(groups.size
    ? [...groups.values()].map((note) => h("li", { class: `quality-note severity-${note.severity}`,
                                                    dataset: { code: note.code } },
      h("span", { class: `severity severity-${note.severity}` }, SEVERITY_WORDS[note.severity] ?? note.severity),
      " ", h("span", { class: "note-message" }, note.message),
      h("details", { class: "note-detail" }, h("summary", {}, "Expert detail"),
        ...note.details.map((detail) => h("p", { "data-detail": "" }, detail)))))
    : [h("li", { class: "no-flags" }, "No quality warnings.")]));
}

/**
 * One sentence per ω component that reads zero, saying why; or that all three are measured.
 * @param {ResultOut} result
 */
function zeroRotationText(result) {
  const omega = result.series?.omega_rad_s || [];
  if (!omega.length) return "This result has no rotation of the back.";
  const zero = [0, 1, 2].filter((i) => column(omega, i).every((v) => v === null || Math.abs(v) < 1e-9));
  if (!zero.length) return "All three rotations of the back (roll, yaw and pitch) were measured.";
  const codes = new Set((result.quality_notes || []).map((n) => n.code));
  const why = codes.has("rotation.markers_in_line") || codes.has("rotation.weak_axis")
    ? "the three markers lie nearly on one line, and rotation about that line moves none of them; move the "
      + "middle marker about 10 cm below the line of the other two to measure it"
    : codes.has("rig.weak_depth")
      ? "the cameras stand too close together to see the markers move in depth; place them 2-3 m apart"
      : "the markers' layout cannot show it on this recording (see the quality notes)";
  return `${zero.map((i) => `\u03c9${AXES[i]}, ${ROTATION_WORDS[i]},`).join(" and ")} reads zero because ${why}.`;
}

/**
 * @param {HTMLElement} view
 * @param {Partial<ResultSeries>} series
 * @param {string} quantity a key of QUANTITIES
 */
function drawFits(view, series, quantity) {
  const q = QUANTITIES[quantity];
  /** @type {(key: keyof ResultSeries) => unknown[] | null | undefined} the series' rows (t_s too is an array) */
  const rows = (key) => series[key];
  for (const [i, axis] of AXES.entries()) {
    const div = one(view, `[data-chart="fit-${axis}"]`);
    fitChart(div, series.t_s, rows(q.measured) ? column(rows(q.measured), i) : null,
      column(rows(q.fitted), i), rows(q.residual) ? column(rows(q.residual), i) : null,
      { title: `${q.label} of S, ${AXIS_WORDS[axis]}`, unit: q.unit, colour: AXIS_COLOURS[axis] });
  }
  one(view, "[data-fit-note]").textContent =
    `Grey dots: ${q.note}; line: the fitted curve; below: measured minus fitted.`;
}

/**
 * Draw the 3-D tracks, the per-axis fits (with a quantity switch), the weighted acceleration and spectrum.
 * @param {HTMLElement} view
 * @param {ResultOut} result
 */
export function drawAnalysis(view, result) {
  /** @type {Partial<ResultSeries>} */
  const series = result.series || {};
  // markers_position_m: per frame, [x, y, z] of each marker (the schema says only "list")
  const markers = /** @type {((number | null)[] | null)[][] | null | undefined} */ (series.markers_position_m);
  tracks3dChart(one(view, '[data-chart="tracks3d"]'), series.t_s, markers, series.position_m);
  const select = one(view, "[data-fit-quantity]", HTMLSelectElement);
  select.replaceChildren(...Object.entries(QUANTITIES).map(([key, q]) => h("option", { value: key }, q.label)));
  select.addEventListener("change", () => drawFits(view, series, select.value));
  drawFits(view, series, select.value || "position");
  weightedChart(one(view, '[data-chart="weighted"]'), series.t_s, column(series.acceleration_m_s2, 1),
    series.acc_y_wb_m_s2, series.acc_y_wk_m_s2);
  spectrumChart(one(view, '[data-chart="spectrum"]'), result.spectrum);
  one(view, "[data-zero-rotation]").textContent = zeroRotationText(result);
  const strides = result.strides_analysed;
  one(view, "[data-strides]").textContent = strides != null && Number.isFinite(strides)
    ? `${strides} whole stride${strides === 1 ? "" : "s"} analysed` : "";
}
