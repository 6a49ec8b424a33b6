// Numbers, units and indicator names for display. The service's constants (the indicator table, the
// gaits, the exposure caveat) are not copied here: js/glossary.js loads them from GET /api/indicators and
// GET /api/glossary before the first page is drawn (app.js), and fills the tables below.

/**
 * What an indicator key means (GET /api/indicators merged with the glossary's indicator entries).
 * @typedef {object} IndicatorInfo
 * @property {string} unit
 * @property {string} label
 * @property {"lower" | "higher" | null} [better] which way is more comfortable (null: neither)
 * @property {string} [short] one line on what it means
 * @property {boolean} [expert] folded under "expert detail"
 * @property {boolean} [comfort] one of the thesis's eight comfort indicators
 */

/** @typedef {import("./api-types").JobOut} Job a job, as the API answers it */

/**
 * The gait codes in the service's order (saddlescope.core.vibration.GAITS), filled at start.
 * @type {string[]}
 */
export const GAITS = [];

/**
 * Each gait's label ("sitting_trot" -> "sitting trot"), filled at start.
 * @type {Record<string, string>}
 */
const GAIT_LABELS = {};

/**
 * The thesis's eight comfort indicators (8.5), all W_b: the default choice in comparisons. Filled at start.
 * @type {string[]}
 */
export const COMFORT_INDICATORS = [];

let passiveSeatedCaveat = "";
/** @type {Record<string, IndicatorInfo>} */
let indicatorInfo = {};

/**
 * The gaits of the glossary ({code, label}, in its order).
 * @param {{code: string, label: string}[]} entries
 */
export function setGaits(entries) {
  GAITS.splice(0, GAITS.length, ...entries.map((e) => e.code));
  for (const e of entries) GAIT_LABELS[e.code] = e.label;
}

/**
 * The comfort indicators (keys, in the server's order).
 * @param {string[]} keys
 */
export function setComfortIndicators(keys) {
  COMFORT_INDICATORS.splice(0, COMFORT_INDICATORS.length, ...keys);
}

/**
 * The sentence shown with the exposure times (saddlescope.core.vibration.PASSIVE_SEATED_CAVEAT).
 * @param {string} text
 */
export function setPassiveSeatedCaveat(text) {
  passiveSeatedCaveat = text;
}

export function caveatText() {
  return passiveSeatedCaveat;
}

// Merged per indicator: the glossary (labels, units, expert) and /api/indicators (better) both fill it,
// and neither may drop what the other said (a glossary entry has no `better`: replacing the whole entry
// left the leaderboard with no ranked indicator to choose).
/**
 * Add the server's indicator entries (objects with unit, label, better, short, expert).
 * @param {Record<string, Partial<IndicatorInfo>> | null | undefined} info
 */
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

/**
 * The server's entry of an indicator; a key it does not list is said in words, with no unit.
 * @param {unknown} key
 * @returns {IndicatorInfo}
 */
export function indicatorInfoOf(key) {
  const name = String(key ?? "");
  return indicatorInfo[name] || { unit: "", label: name.replaceAll("_", " "), better: null };
}

export function indicatorKeys() {
  return Object.keys(indicatorInfo);
}

/**
 * "m/s^2" -> "m/s²" for text; keeps other units as they are.
 * @param {string | null | undefined} unit
 */
export function prettyUnit(unit) {
  return (unit || "").replace("^2", "\u00b2").replace("^1.75", "\u00b9\u00b7\u2077\u2075");
}

/**
 * "W_b" -> "W_b" as text with the subscript marked up (returns a DocumentFragment).
 * @param {unknown} label
 */
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

/**
 * Plain-text label ("W_b" -> "Wb") for chart axes and option lists.
 * @param {unknown} label
 */
export function labelText(label) {
  return String(label).replace(/W_([a-z])/g, "W$1");
}

/**
 * A number with `digits` significant digits, without exponent for everyday sizes:
 * 0.0110 -> "0.0110", 1234.5 -> "1230" (4 digits: "1235"), null/NaN -> "–".
 * @param {number | string | null | undefined} value
 * @param {number} [digits]
 * @returns {string}
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
 * @param {number | null | undefined} low
 * @param {number | null | undefined} high
 * @param {number} [digits]
 */
export function rangeText(low, high, digits = 3) {
  const open = (/** @type {unknown} */ v) => v === null || v === undefined || v === "";
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

/** @param {string | null | undefined} gait */
export function gaitLabel(gait) {
  return (gait && GAIT_LABELS[gait]) || gait || "";
}

/**
 * A time in hours as a rider says it: 2.083 -> "2 h 05 min", 0.2 -> "12 min", 0.011 -> "under a minute"
 * (no seconds: the times are estimates). The same words as the report (saddlescope.services.results.report.duration_text).
 * @param {number | string | null | undefined} hours
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

/**
 * A job's time in seconds as a person says it: 40 -> "under a minute", 130 -> "about 2 min", 4000 -> "about 1 h 07 min".
 * @param {number | null | undefined} seconds
 */
function secondsText(seconds) {
  const s = Number(seconds);
  if (seconds === null || seconds === undefined || !Number.isFinite(s) || s < 0) return "";
  if (s < 60) return "under a minute";
  const minutes = Math.round(s / 60);
  if (minutes < 60) return `about ${minutes} min`;
  return `about ${Math.floor(minutes / 60)} h ${String(minutes % 60).padStart(2, "0")} min`;
}

/**
 * How long a job took or still needs, in words ("took about 3 min", "about 2 min left"); "" when unknown.
 * @param {Partial<Job> | null | undefined} job
 */
export function jobTimeText(job) {
  if (job?.status === "running" && job.remaining_s != null) return `${secondsText(job.remaining_s)} left`;
  if ((job?.status === "done" || job?.status === "failed") && job.duration_s != null) return `took ${secondsText(job.duration_s)}`;
  if (job?.status === "queued") return "waiting to start";
  return "";
}

/**
 * A riding distance in km as a rider says it: 0.00416 -> "about 4 m", 0.416 -> "about 420 m", 1.23 -> "about 1.2 km"
 * (two significant digits: the distances are estimates). The same words as saddlescope.services.results.report.distance_text.
 * @param {number | string | null | undefined} km
 */
export function distanceText(km) {
  if (km === null || km === undefined || km === "") return "\u2013";
  const d = Number(km);
  if (Number.isNaN(d) || d < 0) return "\u2013";
  if (d === Infinity) return "no limit";
  const twoDigits = (/** @type {number} */ v) => {
    const rounded = Number(v.toPrecision(2));
    return rounded >= 10 ? Math.round(rounded).toLocaleString("en") : String(rounded);
  };
  if (d * 1000 < 1) return "under a metre";
  if (d * 1000 < 10) return `about ${Math.round(d * 1000)} m`;
  if (d * 1000 < 1000) return `about ${twoDigits(d * 1000)} m`;
  return `about ${twoDigits(d)} km`;
}

/**
 * "42 % – analysing the ride" for a job (JobOut: progress_percent, stage_label in the server's words); never "null".
 * @param {Partial<Job> | null | undefined} job
 */
export function jobProgressText(job) {
  const percent = Math.max(0, Math.min(100, Math.round(Number(job?.progress_percent) || 0)));
  const stage = job?.stage_label || "";
  return { percent, stage, text: stage ? `${percent} % \u2013 ${stage}` : `${percent} %` };
}
