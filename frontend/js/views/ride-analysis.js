// The ride page's analysis panels: quality in plain words, 3-D tracks, fitted curves over the measured
// samples with residuals, weighted vertical acceleration and its spectrum, why a rotation reads zero.

import { fitChart, spectrumChart, tracks3dChart, weightedChart } from "../charts.js";
import { h } from "../dom.js";

const SEVERITY_WORDS = { ok: "OK", check: "Check", problem: "Problem" };
const AXES = ["x", "y", "z"];
const AXIS_WORDS = { x: "x, direction of travel", y: "y, vertical (down)", z: "z, sideways" };
const AXIS_COLOURS = { x: "#1f5fa8", y: "#c2410c", z: "#2f855a" };
// ω components as riders name the rotations of the back (x travel, y down, z sideways)
const ROTATION_WORDS = ["roll (about the direction of travel)", "yaw (about the vertical)",
  "pitch (about the sideways axis)"];
const QUANTITIES = {
  position: { label: "Position", unit: "m", measured: "position_m", fitted: "position_fitted_m",
              residual: "position_residual_m", note: "measured: the registered samples" },
  velocity: { label: "Velocity", unit: "m/s", measured: "velocity_measured_m_s", fitted: "velocity_m_s",
              residual: "velocity_residual_m_s", note: "measured: differences of the measured positions" },
  acceleration: { label: "Acceleration", unit: "m/s\u00b2", measured: "acceleration_measured_m_s2",
                  fitted: "acceleration_m_s2", residual: "acceleration_residual_m_s2",
                  note: "measured: second differences of the measured positions" },
};

function column(rows, i) {
  return (rows || []).map((row) => (Array.isArray(row) && Number.isFinite(row[i]) ? row[i] : null));
}

/** The quality notes: the overall line, then one sentence per flag with the expert detail folded away. */
export function showQuality(view, result) {
  const notes = result.quality_notes || [];
  const summary = result.quality_summary || { severity: "ok", message: "" };
  const line = view.querySelector("[data-quality-summary]");
  line.className = `quality-summary severity-${summary.severity}`;
  line.replaceChildren(h("span", { class: `severity severity-${summary.severity}` },
    SEVERITY_WORDS[summary.severity] ?? summary.severity), " ", summary.message || "");
  // flags that ask for the same thing are one line, with each expert sentence behind its toggle
  const groups = new Map();
  for (const note of notes) {
    if (!groups.has(note.message)) groups.set(note.message, { ...note, details: [] });
    groups.get(note.message).details.push(note.detail);
  }
  view.querySelector("[data-quality-notes]").replaceChildren(...(groups.size
    ? [...groups.values()].map((note) => h("li", { class: `quality-note severity-${note.severity}`,
                                                    dataset: { code: note.code } },
      h("span", { class: `severity severity-${note.severity}` }, SEVERITY_WORDS[note.severity] ?? note.severity),
      " ", h("span", { class: "note-message" }, note.message),
      h("details", { class: "note-detail" }, h("summary", {}, "Expert detail"),
        ...note.details.map((detail) => h("p", { "data-detail": "" }, detail)))))
    : [h("li", { class: "no-flags" }, "No quality warnings.")]));
}

/** One sentence per ω component that reads zero, saying why; or that all three are measured. */
export function zeroRotationText(result) {
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

function drawFits(view, series, quantity) {
  const q = QUANTITIES[quantity];
  for (const [i, axis] of AXES.entries()) {
    const div = view.querySelector(`[data-chart="fit-${axis}"]`);
    fitChart(div, series.t_s, series[q.measured] ? column(series[q.measured], i) : null,
      column(series[q.fitted], i), series[q.residual] ? column(series[q.residual], i) : null,
      { title: `${q.label} of S, ${AXIS_WORDS[axis]}`, unit: q.unit, colour: AXIS_COLOURS[axis] });
  }
  view.querySelector("[data-fit-note]").textContent =
    `Grey dots: ${q.note}; line: the fitted curve; below: measured minus fitted.`;
}

/** Draw the 3-D tracks, the per-axis fits (with a quantity switch), the weighted acceleration and spectrum. */
export function drawAnalysis(view, result) {
  const series = result.series || {};
  tracks3dChart(view.querySelector('[data-chart="tracks3d"]'), series.t_s, series.markers_position_m,
    series.position_m);
  const select = view.querySelector("[data-fit-quantity]");
  select.replaceChildren(...Object.entries(QUANTITIES).map(([key, q]) => h("option", { value: key }, q.label)));
  select.addEventListener("change", () => drawFits(view, series, select.value));
  drawFits(view, series, select.value || "position");
  weightedChart(view.querySelector('[data-chart="weighted"]'), series.t_s, column(series.acceleration_m_s2, 1),
    series.acc_y_wb_m_s2, series.acc_y_wk_m_s2);
  spectrumChart(view.querySelector('[data-chart="spectrum"]'), result.spectrum);
  view.querySelector("[data-zero-rotation]").textContent = zeroRotationText(result);
  const strides = result.strides_analysed;
  view.querySelector("[data-strides]").textContent = Number.isFinite(strides)
    ? `${strides} whole stride${strides === 1 ? "" : "s"} analysed` : "";
}
