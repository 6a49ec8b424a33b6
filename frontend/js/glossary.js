// The one glossary of codes the service shows (GET /api/glossary, services/glossary.py): every label of
// an indicator, gait, direction, job kind, clip kind, gravity source or comparison method comes from it,
// so a raw code (`lab_vertical`, `dtw`, `analyze`) never reaches a page. Loaded once at start (it needs no
// sign-in); until it is, and for a code it lacks, the code is said in words (underscores as spaces).

import { get } from "./api.js";
import { setGaitLabels, setIndicatorInfo } from "./format.js";

const entries = new Map(); // "kind:code" -> {kind, code, label, unit, short, expert}
let loading = null;

/** Fetch the glossary once; indicators also refresh format.js's table (labels, units, expert). */
export function loadGlossary() {
  if (!loading) {
    loading = get("/api/glossary").then((list) => {
      for (const e of list || []) entries.set(`${e.kind}:${e.code}`, e);
      const indicators = (list || []).filter((e) => e.kind === "indicator");
      if (indicators.length) {
        setIndicatorInfo(Object.fromEntries(indicators.map((e) => [e.code, { unit: e.unit, label: e.label,
          short: e.short, expert: e.expert }])));
      }
      setGaitLabels(Object.fromEntries((list || []).filter((e) => e.kind === "gait").map((e) => [e.code, e.label])));
      return entries;
    }).catch((error) => {
      loading = null; // a later page tries again
      console.info("glossary not available from the server:", error.message);
      return entries;
    });
  }
  return loading;
}

/** The glossary's entry of `code` of `kind`, or null. */
export function glossaryEntry(kind, code) {
  return entries.get(`${kind}:${code}`) ?? null;
}

/** The label of `code` of `kind` ("lab_vertical" -> "the lab's vertical axis"); never the raw code. */
export function glossaryLabel(kind, code) {
  if (code === null || code === undefined || code === "") return "";
  return glossaryEntry(kind, code)?.label ?? String(code).replaceAll("_", " ");
}
