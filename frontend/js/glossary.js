// The service's own words and constants: the glossary of every code a page shows (GET /api/glossary,
// services/glossary.py: indicators, gaits, directions, job kinds, clip kinds, gravity sources, comparison
// methods, saddle types, the exposure caveat) and the indicator table (GET /api/indicators: which way is
// more comfortable, the comfort indicators). Both are open without sign-in; app.js loads them once at
// start, before the first page is drawn, so a page never shows a guessed label. A code the glossary lacks
// is said in words (underscores as spaces), never as the raw code.

import { get } from "./api.js";
import { setComfortIndicators, setGaits, setIndicatorInfo, setPassiveSeatedCaveat } from "./format.js";

/** @typedef {import("./api-types").GlossaryEntryOut} GlossaryEntry */
/** @typedef {GlossaryEntry["kind"]} GlossaryKind */

/** @type {Map<string, GlossaryEntry>} "kind:code" -> the entry */
const entries = new Map();
/** @type {Promise<void> | null} */
let loading = null;

/**
 * @param {GlossaryEntry[]} glossary
 * @param {import("./api-types").IndicatorOut[]} indicators
 */
function keep(glossary, indicators) {
  entries.clear();
  for (const e of glossary) entries.set(`${e.kind}:${e.code}`, e);
  setIndicatorInfo(Object.fromEntries(indicators.map(({ key, ...info }) => [key, info])));
  setIndicatorInfo(Object.fromEntries(glossaryEntries("indicator").map((e) => [e.code,
    { unit: e.unit, label: e.label, short: e.short, expert: e.expert }])));
  setComfortIndicators(indicators.filter((info) => info.comfort).map((info) => info.key));
  setGaits(glossaryEntries("gait"));
  setPassiveSeatedCaveat(glossaryEntry("caveat", "passive_seated")?.label ?? "");
}

/**
 * Fetch the glossary and the indicator table once (format.js's tables are filled from them). Rejects
 * with the ApiError when the server cannot answer; a later call tries again.
 * @returns {Promise<void>}
 */
export function loadConstants() {
  if (!loading) {
    /** @type {Promise<GlossaryEntry[]>} */
    const glossaryAsked = get("/api/glossary");
    /** @type {Promise<import("./api-types").IndicatorOut[]>} */
    const indicatorsAsked = get("/api/indicators");
    loading = Promise.all([glossaryAsked, indicatorsAsked])
      .then(([glossary, indicators]) => keep(glossary, indicators))
      .catch((error) => {
        loading = null;
        throw error;
      });
  }
  return loading;
}

/**
 * The glossary's entry of `code` of `kind`, or null.
 * @param {GlossaryKind} kind
 * @param {string} code
 * @returns {GlossaryEntry | null}
 */
function glossaryEntry(kind, code) {
  return entries.get(`${kind}:${code}`) ?? null;
}

/**
 * Every entry of `kind`, in the glossary's order.
 * @param {GlossaryKind} kind
 * @returns {GlossaryEntry[]}
 */
export function glossaryEntries(kind) {
  return [...entries.values()].filter((e) => e.kind === kind);
}

/**
 * The label of `code` of `kind` ("lab_vertical" -> "the lab's vertical axis"); never the raw code.
 * @param {GlossaryKind} kind
 * @param {string | null | undefined} code
 * @returns {string}
 */
export function glossaryLabel(kind, code) {
  if (code === null || code === undefined || code === "") return "";
  return glossaryEntry(kind, code)?.label ?? String(code).replaceAll("_", " ");
}
