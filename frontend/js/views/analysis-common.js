// Shared by the comparison, leaderboard and grades pages: read a per-indicator answer in any of the
// shapes the server may use, and re-run a page's query when its form changes.

import { itemsOf } from "../api.js";

/** The part of `answer` about `indicator`: answer[indicator], answer.indicators[indicator], or answer itself. */
export function forIndicator(answer, indicator) {
  if (answer && !Array.isArray(answer) && typeof answer === "object") {
    if (answer[indicator] !== undefined) return answer[indicator];
    if (answer.indicators?.[indicator] !== undefined) return answer.indicators[indicator];
    if (answer.results?.[indicator] !== undefined) return answer.results[indicator];
  }
  return answer;
}

/** Group summaries ({group, n, mean, std, min, max}) out of a comparison answer. */
export function groupsOf(answer, indicator) {
  const part = forIndicator(answer, indicator);
  if (Array.isArray(part)) return part;
  for (const key of ["gaits", "horses", "groups", "entries"]) {
    if (part && Array.isArray(part[key])) return part[key];
  }
  return itemsOf(part);
}

/** Call `run(values)` now and whenever a field of `form` changes; a newer run wins. */
export function onFormChange(form, run) {
  let generation = 0;
  const go = async () => {
    const mine = ++generation;
    const values = Object.fromEntries(new FormData(form).entries());
    await run(values, () => mine === generation);
  };
  form.addEventListener("change", go);
  form.addEventListener("submit", (event) => { event.preventDefault(); go(); });
  return go();
}
