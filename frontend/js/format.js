// Numbers, units and indicator names for display. The indicator table mirrors
// saddlescope.core.vibration.INDICATORS; the server's own list (GET /api/indicators) replaces it when offered.

export const GAITS = ["walk", "sitting_trot", "rising_trot", "canter"];

export const GAIT_LABELS = {
  walk: "walk",
  sitting_trot: "sitting trot",
  rising_trot: "rising trot",
  canter: "canter",
};

// Shown with the exposure times, as in saddlescope.core.vibration.PASSIVE_SEATED_CAVEAT.
export const PASSIVE_SEATED_CAVEAT =
  "The EU 2002/44/EC action and limit values assume a passive, seated person who takes no " +
  "counter-measures against the vibration. A rider compensates actively (the pelvis follows " +
  "the saddle in sitting trot, the trunk swings in canter; in rising trot the rider is not in " +
  "continuous contact with the saddle at all), so the allowed times and distances are far on " +
  "the safe side: read them as relative comfort indicators between horses and gaits, not as " +
  "absolute limits (thesis 8.5).";

const exposure = {};
for (const [basis, basisLabel] of [["a8", "A(8)"], ["vdv", "VDV"]]) {
  for (const level of ["action", "limit"]) {
    for (const w of ["wb", "wk"]) {
      exposure[`t_${basis}_${level}_${w}_h`] = {
        unit: "h", label: `time to the ${basisLabel} exposure ${level} value (W_${w[1]})`, better: "higher" };
      exposure[`d_${basis}_${level}_${w}_km`] = {
        unit: "km", label: `distance to the ${basisLabel} exposure ${level} value (W_${w[1]})`, better: "higher" };
    }
  }
}

let indicatorInfo = {
  acc_y_wb_rms: { unit: "m/s^2", label: "vertical W_b weighted r.m.s. acceleration", better: "lower" },
  acc_y_wk_rms: { unit: "m/s^2", label: "vertical W_k weighted r.m.s. acceleration", better: "lower" },
  vdv_y_wb: { unit: "m/s^1.75", label: "vertical W_b vibration dose value", better: "lower" },
  vdv_y_wk: { unit: "m/s^1.75", label: "vertical W_k vibration dose value", better: "lower" },
  acc_y_max: { unit: "m/s^2", label: "peak unweighted vertical acceleration", better: "lower" },
  crest_factor_y: { unit: "", label: "vertical crest factor (W_b)", better: "lower" },
  ...exposure,
  vel_x_avg_kmh: { unit: "km/h", label: "average speed in the direction of travel", better: null },
  amplitude_y_m: { unit: "m", label: "peak-to-peak vertical displacement of the saddle point", better: null },
  stride_frequency_hz: { unit: "Hz", label: "stride frequency", better: null },
  crest_factor_y_wk: { unit: "", label: "vertical crest factor (W_k)", better: "lower" },
  acc_y_rms: { unit: "m/s^2", label: "unweighted vertical r.m.s. acceleration", better: "lower" },
  duration_s: { unit: "s", label: "analysed duration (whole number of periods)", better: null },
};

// The thesis's eight comfort indicators (8.5), all W_b: the default choice in comparisons.
export const COMFORT_INDICATORS = [
  "acc_y_wb_rms", "vdv_y_wb", "acc_y_max", "crest_factor_y", "t_a8_limit_wb_h", "d_a8_limit_wb_km",
  "vel_x_avg_kmh", "amplitude_y_m",
];

/** Replace the built-in indicator table with the server's (objects with unit, label, better). */
// Merged per indicator: the glossary (labels, units, expert) and /api/indicators (better) arrive in
// either order, and neither may drop what the other said (a glossary entry has no `better`: replacing
// the whole entry left the leaderboard with no ranked indicator to choose).
export function setIndicatorInfo(info) {
  if (!info || typeof info !== "object") return;
  const merged = { ...indicatorInfo };
  for (const [key, entry] of Object.entries(info)) {
    if (!key || !entry || typeof entry !== "object") continue;
    const defined = Object.fromEntries(Object.entries(entry).filter(([, v]) => v !== undefined && v !== null));
    merged[key] = { ...(indicatorInfo[key] || {}), ...defined };
  }
  indicatorInfo = merged;
}

export function indicatorInfoOf(key) {
  const name = String(key ?? "");
  return indicatorInfo[name] || { unit: unitFromKey(name), label: name.replaceAll("_", " "), better: null };
}

export function indicatorKeys() {
  return Object.keys(indicatorInfo);
}

function unitFromKey(key) {
  for (const [suffix, unit] of [["_kmh", "km/h"], ["_km", "km"], ["_hz", "Hz"], ["_h", "h"], ["_s", "s"], ["_m", "m"]]) {
    if (key.endsWith(suffix)) return unit;
  }
  return "";
}

/** "m/s^2" -> "m/s²" for text; keeps other units as they are. */
export function prettyUnit(unit) {
  return (unit || "").replace("^2", "\u00b2").replace("^1.75", "\u00b9\u00b7\u2077\u2075");
}

/** "W_b" -> "W_b" as text with the subscript marked up (returns a DocumentFragment). */
export function labelFragment(label) {
  const fragment = document.createDocumentFragment();
  const parts = String(label).split(/(W_[a-z])/);
  for (const part of parts) {
    const m = /^W_([a-z])$/.exec(part);
    if (m) {
      fragment.append("W");
      const sub = document.createElement("sub");
      sub.textContent = m[1];
      fragment.append(sub);
    } else if (part) {
      fragment.append(part);
    }
  }
  return fragment;
}

/** Plain-text label ("W_b" -> "Wb") for chart axes and option lists. */
export function labelText(label) {
  return String(label).replace(/W_([a-z])/g, "W$1");
}

/**
 * A number with `digits` significant digits, without exponent for everyday sizes:
 * 0.0110 -> "0.0110", 1234.5 -> "1230" (4 digits: "1235"), null/NaN -> "–".
 */
export function fmt(value, digits = 3) {
  if (value === null || value === undefined || value === "") return "\u2013";
  const x = Number(value);
  if (!Number.isFinite(x)) return x === Infinity ? "\u221e" : "\u2013";
  if (x === 0) return "0";
  const magnitude = Math.floor(Math.log10(Math.abs(x)));
  if (magnitude >= digits - 1) {
    if (magnitude >= 9) return x.toExponential(digits - 1);
    return Number(x.toPrecision(digits)).toString(); // 12345.6 -> "12300": no more digits than asked for
  }
  if (magnitude < -6) return x.toExponential(digits - 1);
  return x.toFixed(digits - 1 - magnitude);
}

// No page shows a number with more digits than this (issue 37): beyond it a reading claims a precision
// the measurement has not, and a club stops trusting the page.
export const MAX_DIGITS = 4;

/**
 * A 95 % interval "low–high" (no unit) that never reads as one value: ends that show alike at `digits`
 * significant digits get one more digit (up to MAX_DIGITS), and ends alike even then read "± under 0.01"
 * (the interval is narrower than the last digit a page shows). An open end (null) is "−∞" or "∞".
 * The report words intervals the same way (saddlescope.services.results.report.range_text).
 */
export function rangeText(low, high, digits = 3) {
  const open = (v) => v === null || v === undefined || v === "";
  if (open(low) || open(high)) return `${open(low) ? "−∞" : fmt(low, digits)}–${open(high) ? "∞" : fmt(high, digits)}`;
  for (let d = digits; d <= Math.max(digits, MAX_DIGITS); d += 1) {
    const [a, b] = [fmt(low, d), fmt(high, d)];
    if (a !== b) return `${a}–${b}`;
  }
  const size = Math.max(Math.abs(Number(low)), Math.abs(Number(high)));
  if (!(size > 0)) return "± 0";
  // the place of the last digit shown at MAX_DIGITS: both ends lie within it
  const place = 10 ** (Math.floor(Math.log10(size)) - (Math.max(digits, MAX_DIGITS) - 1));
  return `± under ${fmt(place, 1)}`;
}

export function fmtUnit(value, unit, digits = 3) {
  const text = fmt(value, digits);
  return unit && text !== "\u2013" ? `${text} ${prettyUnit(unit)}` : text;
}

/** The glossary's gait labels (js/glossary.js) replace the built-in ones. */
export function setGaitLabels(labels) {
  Object.assign(GAIT_LABELS, labels);
}

export function gaitLabel(gait) {
  return GAIT_LABELS[gait] || gait || "";
}

/**
 * A time in hours as a rider says it: 2.083 -> "2 h 05 min", 0.2 -> "12 min", 0.011 -> "under a minute"
 * (no seconds: the times are estimates). The same words as the report (saddlescope.services.results.report.duration_text).
 */
export function durationText(hours) {
  if (hours === null || hours === undefined || hours === "") return "\u2013";
  const h = Number(hours);
  if (Number.isNaN(h) || h < 0) return "\u2013";
  if (h === Infinity) return "no limit";
  if (h * 60 < 1) return "under a minute";
  const minutes = Math.round(h * 60);
  if (minutes < 60) return `${minutes} min`;
  if (h >= 100) return `${Math.round(h).toLocaleString("en")} h`;
  return `${Math.floor(minutes / 60)} h ${String(minutes % 60).padStart(2, "0")} min`;
}

/** A job's time in seconds as a person says it: 40 -> "under a minute", 130 -> "about 2 min", 4000 -> "about 1 h 07 min". */
export function secondsText(seconds) {
  const s = Number(seconds);
  if (seconds === null || seconds === undefined || !Number.isFinite(s) || s < 0) return "";
  if (s < 60) return "under a minute";
  const minutes = Math.round(s / 60);
  if (minutes < 60) return `about ${minutes} min`;
  return `about ${Math.floor(minutes / 60)} h ${String(minutes % 60).padStart(2, "0")} min`;
}

/** How long a job took or still needs, in words ("took about 3 min", "about 2 min left"); "" when unknown. */
export function jobTimeText(job) {
  if (job?.status === "running" && job.remaining_s != null) return `${secondsText(job.remaining_s)} left`;
  if ((job?.status === "done" || job?.status === "failed") && job.duration_s != null) return `took ${secondsText(job.duration_s)}`;
  if (job?.status === "queued") return "waiting to start";
  return "";
}

/**
 * A riding distance in km as a rider says it: 0.00416 -> "about 4 m", 0.416 -> "about 420 m", 1.23 -> "about 1.2 km"
 * (two significant digits: the distances are estimates). The same words as saddlescope.services.results.report.distance_text.
 */
export function distanceText(km) {
  if (km === null || km === undefined || km === "") return "\u2013";
  const d = Number(km);
  if (Number.isNaN(d) || d < 0) return "\u2013";
  if (d === Infinity) return "no limit";
  const twoDigits = (v) => {
    const rounded = Number(v.toPrecision(2));
    return rounded >= 10 ? Math.round(rounded).toLocaleString("en") : String(rounded);
  };
  if (d * 1000 < 1) return "under a metre";
  if (d * 1000 < 10) return `about ${Math.round(d * 1000)} m`;
  if (d * 1000 < 1000) return `about ${twoDigits(d * 1000)} m`;
  return `about ${twoDigits(d)} km`;
}

// A job's stage names in plain words, where the job does not carry its own stage_label.
const STAGE_WORDS = {
  probe: "checking the clips", assemble: "gathering the clips", calibrate: "calibrating the cameras",
  analyze: "analysing the ride", analyse: "analysing the ride", similarity: "comparing rides",
  selftest: "self-test", queued: "waiting in the queue",
};

/** "42 % – analysing the ride" for a job ({progress_percent?, progress?, stage_label?, stage?}); never "null". */
export function jobProgressText(job) {
  const raw = job?.progress_percent ?? (Number.isFinite(job?.progress) ? job.progress * 100 : null);
  const percent = Number.isFinite(Number(raw)) && raw !== null ? Math.max(0, Math.min(100, Math.round(Number(raw)))) : 0;
  const stage = job?.stage_label || STAGE_WORDS[job?.stage] || (job?.stage ? String(job.stage).replaceAll("_", " ") : "");
  return { percent, stage, text: stage ? `${percent} % \u2013 ${stage}` : `${percent} %` };
}
