// Jobs: filtered and paged by the server (state in the URL: #/jobs?status=failed&page=2), progress as a
// percentage with what the job is doing in plain words, "waiting for a worker" notes shown
// prominently, polled while any job on the page is queued or running. Cancel and retry are shown only
// to those allowed (the ride's maker and admins: can("job.cancel", owner)).

import { get, itemsOf, post } from "../api.js";
import { announce, formatDate, h, messageOf, one, page, showError } from "../dom.js";
import { apiParams, bindFilterForm, listState, pager } from "../pager.js";
import { poll } from "../poll.js";
import { can } from "../session.js";
import { jobTimeText } from "../format.js";
import { glossaryLabel } from "../glossary.js";

const UNFINISHED = new Set(["queued", "running"]);
const FILTERS = ["status", "kind", "ride_id"];

/** @typedef {import("../api-types").JobOut} JobOut */

/** @param {JobOut} job */
function percentOf(job) {
  if (job.progress_percent !== undefined && Number.isFinite(job.progress_percent)) return job.progress_percent;
  return Math.round((job.progress ?? 0) * 100);
}

/** @param {JobOut} job */
function progressCell(job) {
  const percent = percentOf(job);
  return h("td", { class: "progress-cell" },
    h("progress", { max: "1", value: String(job.progress ?? 0), "aria-label": `Job ${job.id} progress`,
                    "aria-valuetext": `${percent} percent` }),
    h("span", { class: "num", "data-job-percent": true }, ` ${percent}\u00a0%`));
}

/** @param {JobOut} job */
function doingCell(job) {
  const label = job.stage_label || job.stage || "";
  return h("td", { class: "stage" },
    h("span", { "data-job-stage": true }, label),
    job.note && UNFINISHED.has(job.status) ? h("strong", { class: "job-note", role: "status", "data-job-note": true }, job.note) : null,
    job.failure ? h("span", { class: "error", "data-job-failure": true }, job.failure.sentence)
      : job.error ? h("span", { class: "error" }, job.error) : null);
}

/** @param {HTMLSelectElement} select */
async function fillKinds(select) {
  try {
    /** @type {import("../api-types").JobKindOut[]} */
    const kinds = await get("/api/jobs/kinds");
    select.append(...kinds.map((kind) => h("option", { value: kind.name }, glossaryLabel("job_kind", kind.name))));
  } catch (error) {
    console.info("job kinds not available:", messageOf(error));
  }
}

/**
 * @param {HTMLElement} view
 * @param {Record<string, string>} params
 * @param {URLSearchParams} query
 */
export async function mountJobs(view, params, query) {
  view.append(page("jobs"));
  const state = listState(query, { filters: FILTERS, sort: "-id" });
  const form = one(view, "[data-jobs-filter]", HTMLFormElement);
  const panel = /** @type {HTMLElement} */ (one(view, "[data-jobs-table]").closest(".panel"));
  const table = one(view, "[data-jobs-table]", HTMLTableElement);
  const empty = one(view, "[data-jobs-empty]");
  const note = one(view, "[data-jobs-note]");
  const pagerSlot = one(view, "[data-jobs-pager]");
  panel.prepend(h("p", { class: "form-error", role: "alert", "data-form-error": true, hidden: true }));
  /** @type {Map<number, string>} */
  const lastStatus = new Map();

  /**
   * @param {JobOut} job
   * @param {"cancel" | "retry"} action
   */
  async function act(job, action) {
    try {
      await post(`/api/jobs/${job.id}/${action}`);
      announce(`Job ${job.id}: ${action} requested.`);
      poller.restart();
    } catch (error) {
      showError(panel, error);
    }
  }

  /**
   * @param {JobOut} job
   * @param {"cancel" | "retry"} action
   * @param {string} label
   */
  function actionButton(job, action, label) {
    return h("button", { type: "button", class: "link-button", "data-permission": `job.${action}`,
                         onclick: () => act(job, action), "aria-label": `${label} job ${job.id}` }, label);
  }

  /** @param {JobOut} job */
  function row(job) {
    const actions = [];
    if (UNFINISHED.has(job.status) && can("job.cancel", job.owner_id)) actions.push(actionButton(job, "cancel", "Cancel"));
    if ((job.status === "failed" || job.status === "cancelled") && can("job.retry", job.owner_id)) {
      actions.push(actionButton(job, "retry", "Retry"));
    }
    return h("tr", { dataset: { jobId: job.id, status: job.status } },
      h("td", {}, `#${job.id}`),
      h("td", {}, glossaryLabel("job_kind", job.kind)),
      h("td", {}, job.ride_id ? h("a", { href: `#/rides/${job.ride_id}`, "data-job-ride": true },
        job.ride_label || `Ride ${job.ride_id}`) : "\u2013"),
      h("td", {}, h("span", { class: `badge status-${job.status}` }, job.status)),
      progressCell(job),
      doingCell(job),
      h("td", { class: "nowrap", "data-job-time": true }, jobTimeText(job) || "\u2013"),
      h("td", { class: "nowrap" }, formatDate(job.created_at)),
      h("td", { class: "actions" }, ...actions));
  }

  async function refresh() {
    /** @type {import("../api-types").Page_JobOut_} */
    let answer;
    try {
      answer = await get("/api/jobs", { params: apiParams(state) });
      showError(panel, null);
    } catch (error) {
      showError(panel, error);
      return true; // keep trying: the server may be restarting
    }
    /** @type {JobOut[]} */
    const jobs = itemsOf(answer);
    table.tBodies[0].replaceChildren(...jobs.map(row));
    /** @type {HTMLElement} */ (table.closest(".table-wrap")).hidden = !jobs.length;
    empty.hidden = jobs.length > 0;
    pagerSlot.replaceChildren(pager(answer, state, { noun: "jobs" }));
    for (const job of jobs) {
      const before = lastStatus.get(job.id);
      if (before && before !== job.status) announce(`Job ${job.id} is ${job.status}.`);
      lastStatus.set(job.id, job.status);
    }
    const active = jobs.filter((job) => UNFINISHED.has(job.status));
    const waiting = active.find((job) => job.note);
    note.classList.toggle("warning", Boolean(waiting));
    note.textContent = waiting ? `Job #${waiting.id} is ${waiting.note}.`
      : active.length ? `${active.length} job${active.length > 1 ? "s" : ""} in progress; updating live.`
        : "No job in progress on this page.";
    return active.length > 0 ? true : 10000; // a new job may start elsewhere: keep looking, slowly
  }

  await fillKinds(one(form, "[data-jobs-kinds]", HTMLSelectElement));
  bindFilterForm(form, state);
  const poller = poll(refresh);
  return () => poller.stop();
}
