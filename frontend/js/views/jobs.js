// Jobs with live progress: polled while any is queued or running; cancel and retry.

import { get, itemsOf, post } from "../api.js";
import { announce, formatDate, h, page, showError } from "../dom.js";
import { poll } from "../poll.js";

const UNFINISHED = new Set(["queued", "running"]);

function progressCell(job) {
  const percent = Math.round((job.progress ?? 0) * 100);
  return h("td", { class: "progress-cell" },
    h("progress", { max: "1", value: String(job.progress ?? 0), "aria-label": `Job ${job.id} progress`,
                    "aria-valuetext": `${percent} percent` }),
    h("span", { class: "num" }, ` ${percent} %`));
}

export async function mountJobs(view) {
  view.append(page("jobs"));
  const panel = view.querySelector(".panel");
  const table = view.querySelector("[data-jobs-table]");
  const empty = view.querySelector("[data-jobs-empty]");
  const note = view.querySelector("[data-jobs-note]");
  panel.prepend(h("p", { class: "form-error", role: "alert", "data-form-error": true, hidden: true }));
  const lastStatus = new Map();

  async function act(job, action) {
    try {
      await post(`/api/jobs/${job.id}/${action}`);
      announce(`Job ${job.id}: ${action} requested.`);
      poller.now();
    } catch (error) {
      showError(panel, error);
    }
  }

  function row(job) {
    const actions = [];
    if (UNFINISHED.has(job.status)) {
      actions.push(h("button", { type: "button", class: "link-button", onclick: () => act(job, "cancel"),
                                 "aria-label": `Cancel job ${job.id}` }, "Cancel"));
    } else if (job.status === "failed" || job.status === "cancelled") {
      actions.push(h("button", { type: "button", class: "link-button", onclick: () => act(job, "retry"),
                                 "aria-label": `Retry job ${job.id}` }, "Retry"));
    }
    return h("tr", { dataset: { jobId: job.id, status: job.status } },
      h("td", {}, `#${job.id}`),
      h("td", {}, job.kind),
      h("td", {}, job.ride_id ? h("a", { href: `#/rides/${job.ride_id}` }, `#${job.ride_id}`) : "\u2013"),
      h("td", {}, h("span", { class: `badge status-${job.status}` }, job.status)),
      progressCell(job),
      h("td", { class: "stage" }, job.error ? h("span", { class: "error" }, job.error) : job.stage ?? ""),
      h("td", {}, formatDate(job.created_at)),
      h("td", { class: "actions" }, ...actions));
  }

  async function refresh() {
    let jobs;
    try {
      jobs = itemsOf(await get("/api/jobs", { params: { limit: 100 } })).sort((a, b) => b.id - a.id);
      showError(panel, null);
    } catch (error) {
      showError(panel, error);
      return true; // keep trying: the server may be restarting
    }
    table.tBodies[0].replaceChildren(...jobs.map(row));
    table.hidden = !jobs.length;
    empty.hidden = jobs.length > 0;
    for (const job of jobs) {
      const before = lastStatus.get(job.id);
      if (before && before !== job.status) announce(`Job ${job.id} is ${job.status}.`);
      lastStatus.set(job.id, job.status);
    }
    const active = jobs.filter((job) => UNFINISHED.has(job.status)).length;
    note.textContent = active ? `${active} job${active > 1 ? "s" : ""} in progress; updating live.` : "No job in progress.";
    return active > 0 ? true : 10000; // a new job may start elsewhere: keep looking, slowly
  }

  const poller = poll(refresh);
  return () => poller.stop();
}
