// Horses ranked per gait and indicator, most comfortable first (the server ranks; we show).

import { get } from "../api.js";
import { h, page, showError } from "../dom.js";
import { fmt, gaitLabel, indicatorInfoOf, labelText, prettyUnit } from "../format.js";
import { fillOptions } from "../options.js";
import { groupsOf, onFormChange } from "./analysis-common.js";

export async function mountLeaderboard(view, _params, query) {
  view.append(page("leaderboard"));
  const form = view.querySelector("[data-leaderboard-form]");
  const table = view.querySelector("[data-leaderboard-table]");
  const empty = view.querySelector("[data-leaderboard-empty]");
  const note = view.querySelector("[data-leaderboard-note]");
  const section = form.closest("section");
  await fillOptions(view);
  for (const name of ["gait", "indicator"]) if (query.get(name)) form.elements[name].value = query.get(name);

  await onFormChange(form, async ({ gait, indicator }, current) => {
    let answer;
    let rows;
    try {
      answer = await get("/api/leaderboard", { params: { gait, indicator } });
      rows = groupsOf(answer, indicator);
    } catch (error) {
      if (current()) showError(section, error);
      return;
    }
    if (!current()) return;
    showError(section, null);
    const info = indicatorInfoOf(indicator);
    const unit = prettyUnit(info.unit);
    view.querySelector("[data-value-head]").textContent = unit ? `Mean (${unit})` : "Mean";
    note.textContent = `${gaitLabel(gait)}, ${labelText(info.label)}: ` +
      `${(answer.better ?? info.better) === "higher" ? "higher" : "lower"} is more comfortable.`;
    table.tBodies[0].replaceChildren(...rows.map((row) => h("tr", { dataset: { horse: row.horse } },
      h("td", { class: "rank" }, String(row.rank)),
      h("th", { scope: "row" }, row.horse_id ? h("a", { href: `#/horses/${row.horse_id}` }, row.horse) : row.horse),
      h("td", { class: "num" }, String(row.n)),
      h("td", { class: "num", dataset: { value: row.mean } }, fmt(row.mean)),
      h("td", { class: "num" }, fmt(row.std)),
      h("td", { class: "num" }, fmt(row.min)),
      h("td", { class: "num" }, fmt(row.max)))));
    table.hidden = !rows.length;
    empty.hidden = rows.length > 0;
  });
}
