// Shared by the comparison, leaderboard, grades, horse and saddle pages: re-run a page's query when its
// form changes.

/**
 * Call `run(values)` now and whenever a field of `form` changes; a newer run wins (`current()` says whether
 * this run is still the newest).
 * @param {HTMLFormElement} form a form of selects and boxes (no file fields: every value is text)
 * @param {(values: Record<string, string>, current: () => boolean) => Promise<void>} run
 * @returns {Promise<void>}
 */
export function onFormChange(form, run) {
  let generation = 0;
  const go = async () => {
    const mine = ++generation;
    const values = /** @type {Record<string, string>} */ (Object.fromEntries(new FormData(form).entries()));
    await run(values, () => mine === generation);
  };
  form.addEventListener("change", go);
  form.addEventListener("submit", (event) => { event.preventDefault(); go(); });
  return go();
}
