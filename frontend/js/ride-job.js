// A ride's analysis job on its page, followed live: waiting, running (percentage, what it does, the
// expected remaining time), done, or failed with one sentence naming the clip and camera and what to do,
// and the way to do it here: replace that clip (the other clips kept), calibrate the rig again (or use the
// ride's own calibration clips for it), or run the analysis again.

import { get, getAll, patch, post } from "./api.js";
import { h, messageOf, one } from "./dom.js";
import { jobProgressText, jobTimeText } from "./format.js";
import { can } from "./session.js";
import { uploadResumable } from "./uploader.js";

/** @typedef {import("./api-types").JobOut} JobOut */
/** @typedef {import("./api-types").RideDetail} RideDetail */
/** @typedef {import("./api-types").FailureOut} FailureOut */
/**
 * Follow job `jobId` on the page (undefined or null: the one followed already); `thenAnalyse`: analyse the
 * ride once it is done (a calibration).
 * @typedef {(jobId?: number | null, options?: {thenAnalyse?: boolean}) => void} Follow
 */

// A ride's status badge while its job runs (the ride row changes only at the job's ends).
/** @type {Record<JobOut["status"], string>} */
const BADGE_WORDS = { queued: "queued", running: "analysing", done: "analysed", failed: "failed", cancelled: "cancelled" };

/**
 * The ride's status badge text and class for a job's status (an analysis job; other kinds leave it).
 * @param {JobOut | null} job
 * @param {string} rideStatus
 */
export function badgeFor(job, rideStatus) {
  if (!job || job.kind !== "analyze") return { status: rideStatus, text: rideStatus };
  const status = job.status === "done" ? "analysed" : job.status === "running" ? "processing" : job.status;
  return { status, text: BADGE_WORDS[job.status] ?? rideStatus };
}

/**
 * True when the ride has its own calibration clip of every camera (a bundle's): it can calibrate its rig.
 * @param {RideDetail} ride
 */
export function hasOwnCalibration(ride) {
  const cams = new Set((ride.recordings || []).filter((r) => r.clip_kind === "calibration").map((r) => r.camera_role));
  return ["left", "middle", "right"].every((c) => cams.has(c));
}

/**
 * @param {RideDetail} ride
 * @param {string} kind
 * @param {string} camera
 */
function ownsClip(ride, kind, camera) {
  return (ride.recordings || []).some((r) => r.clip_kind === kind && r.camera_role === camera);
}

/**
 * @param {RideDetail} ride
 * @param {FailureOut & {camera: string, clip_kind: string}} failure a clip's (its camera and kind known)
 * @param {Follow} follow
 */
function replaceClipForm(ride, failure, follow) {
  const { camera, clip_kind: kind } = failure;
  const id = `replace-${kind}-${camera}`;
  const error = h("p", { class: "form-error", role: "alert", hidden: true });
  const status = h("span", { class: "hint", role: "status" });
  const input = h("input", { type: "file", id, name: "file", accept: "video/*,.mp4,.mov,.avi,.mkv", required: true,
                             "data-replace-file": "" });
  const form = h("form", { class: "replace-clip", "data-replace-clip": `${kind}/${camera}` },
    h("label", { for: id }, `New ${kind} clip of the ${camera} camera`), input,
    h("button", { type: "submit" }, "Upload it and analyse again"), status, error);
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    const file = input.files?.[0];
    if (!file) return;
    const button = one(form, "button", HTMLButtonElement);
    button.disabled = true;
    error.hidden = true;
    status.textContent = `Uploading ${file.name}\u2026`;
    try {
      const target = /** @type {import("./uploader.js").UploadTarget} */ ({ target: "ride_clip", ride_id: ride.id, clip_kind: kind, camera });
      const answer = await uploadResumable(file, target,
        { onProgress: (sent) => { status.textContent = `Uploading: ${Math.round((100 * sent) / Math.max(file.size, 1))} %`; } });
      /** @type {number | undefined} */
      const jobId = answer?.job_id ?? /** @type {JobOut | null} */ (await post(`/api/rides/${ride.id}/analyze`))?.id;
      status.textContent = "Uploaded; the analysis starts again.";
      follow(jobId);
    } catch (err) {
      button.disabled = false;
      status.textContent = "";
      error.textContent = messageOf(err);
      error.hidden = false;
    }
  });
  return form;
}

/**
 * @param {string} text
 * @param {`data-${string}`} hook its data- attribute
 * @param {() => Promise<void>} run
 */
function actionButton(text, hook, run) {
  const button = h("button", { type: "button", [hook]: "" }, text);
  button.addEventListener("click", async () => {
    button.disabled = true;
    try {
      await run();
    } catch (err) {
      button.disabled = false;
      button.after(h("p", { class: "form-error", role: "alert" }, messageOf(err)));
    }
  });
  return button;
}

/**
 * "Use this ride's calibration for the rig": a calibrate_rig job from the ride's clips, then the analysis again.
 * @param {RideDetail} ride
 * @param {Follow} follow
 */
export function useRideCalibrationButton(ride, follow) {
  return actionButton("Use this ride's calibration for the rig", "data-use-ride-calibration", async () => {
    /** @type {JobOut} */
    const job = await post(`/api/rides/${ride.id}/calibrate-rig`);
    follow(job.id, { thenAnalyse: true });
  });
}

// "Pick another calibration": the club's other calibrated rigs (one calibrated after the cameras moved),
// the ride moved to the chosen one and analysed again.
/**
 * @param {RideDetail} ride
 * @param {Follow} follow
 */
function pickRigForm(ride, follow) {
  const id = `ride-${ride.id}-rig`;
  const select = h("select", { id, name: "rig_id", "data-pick-rig": "" });
  const error = h("p", { class: "form-error", role: "alert", hidden: true });
  const form = h("form", { class: "replace-clip", hidden: true },
    h("label", { for: id }, "Or analyse it with another rig's calibration"), select,
    h("button", { type: "submit" }, "Use this rig and analyse again"), error);
  /** @type {Promise<import("./api-types").RigOut[]>} */
  const rigsAsked = getAll("/api/rigs");
  rigsAsked.then((all) => {
    const rigs = all.filter((rig) => rig.calibrated && rig.id !== ride.rig_id);
    select.replaceChildren(...rigs.map((rig) => h("option", { value: String(rig.id) }, rig.name)));
    form.hidden = !rigs.length;
  }).catch((err) => console.info("rigs not available:", messageOf(err)));
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    const button = one(form, "button", HTMLButtonElement);
    button.disabled = true;
    try {
      await patch(`/api/rides/${ride.id}`, { rig_id: Number(select.value) });
      follow(/** @type {JobOut | null} */ (await post(`/api/rides/${ride.id}/analyze`))?.id);
    } catch (err) {
      button.disabled = false;
      error.textContent = messageOf(err);
      error.hidden = false;
    }
  });
  return form;
}

/**
 * @param {RideDetail} ride
 * @param {JobOut} job
 * @param {FailureOut | null | undefined} failure
 * @param {{follow: Follow}} handlers
 */
function failureActions(ride, job, failure, { follow }) {
  /** @type {HTMLElement[]} */
  const actions = [];
  const mayChange = can("ride.create");
  if (failure?.action === "replace_clip" && failure.camera && failure.clip_kind && mayChange) {
    if (ownsClip(ride, failure.clip_kind, failure.camera) || failure.clip_kind === "motion") {
      // camera and clip_kind are known: the condition above
      actions.push(replaceClipForm(ride, /** @type {FailureOut & {camera: string, clip_kind: string}} */ (failure), follow));
    } else if (ride.rig_id) {  // the rig's shared clip (its static, plumb or calibration clip)
      actions.push(h("p", {}, h("a", { href: `#/rigs/${ride.rig_id}` }, `Replace the rig's ${failure.clip_kind} clip`),
        " on the rig's page, then run the analysis again here."));
    }
  }
  if (failure?.action === "recalibrate_rig" && mayChange) {
    if (ride.rig_id) {
      actions.push(h("p", {}, h("a", { href: `#/rigs/${ride.rig_id}`, "data-recalibrate-link": "" },
        "Calibrate the rig again"), " on its page (upload new calibration clips), then run the analysis again here."));
    }
    if (ride.rig_id && hasOwnCalibration(ride)) actions.push(useRideCalibrationButton(ride, follow));
    actions.push(pickRigForm(ride, follow));
  }
  if (can("job.retry", ride.created_by ?? null)) {
    actions.push(actionButton("Run the analysis again", "data-retry-job", async () => {
      const again = job.kind === "analyze" ? await post(`/api/jobs/${job.id}/retry`) : await post(`/api/rides/${ride.id}/analyze`);
      follow(/** @type {JobOut | null} */ (again)?.id ?? job.id);
    }));
  }
  return actions;
}

/**
 * The job's state in `slot`: progress while it runs, the failure's sentence and its remedies once failed.
 * @param {HTMLElement} slot
 * @param {RideDetail} ride
 * @param {JobOut} job
 * @param {{follow: Follow}} handlers
 */
export function showJob(slot, ride, job, handlers) {
  const { percent, stage } = jobProgressText(job);
  const what = job.kind === "calibrate_rig" ? "Calibrating the rig" : "Analysis";
  const time = jobTimeText(job);
  /** @type {HTMLElement[]} */
  const parts = [];
  if (job.status === "queued") {
    parts.push(h("p", { "data-job-status": "queued" }, `${what}: waiting to start.`));
  } else if (job.status === "running") {
    const text = [`${percent} %`, stage, time].filter(Boolean).join(" \u00b7 ");
    parts.push(h("p", { "data-job-status": "running" }, `${what}: running.`),
      h("div", { class: "job-progress" },
        h("progress", { max: "100", value: String(percent), "aria-label": `${what} progress`,
                        "aria-valuetext": `${percent} percent${stage ? `, ${stage}` : ""}` }),
        h("span", { class: "job-progress-text", "data-job-progress": "" }, text)));
  } else if (job.status === "done") {
    parts.push(h("p", { "data-job-status": "done" }, `${what}: finished${time ? ` (${time})` : ""}.`));
    if (job.kind === "calibrate_rig" && can("ride.create")) {  // the rig calibrated anew: analyse the ride with it
      parts.push(actionButton("Analyse the ride with the new calibration", "data-analyse-now", async () => {
        handlers.follow(/** @type {JobOut | null} */ (await post(`/api/rides/${ride.id}/analyze`))?.id);
      }));
    }
  } else {
    const failure = job.failure;
    const sentence = job.status === "cancelled" ? `${what} was cancelled.`
      : failure?.sentence ?? "The analysis stopped with an error.";
    parts.push(h("p", { class: "form-error failure", role: "alert", "data-job-status": job.status,
                        "data-failure-sentence": "" }, sentence));
    parts.push(...failureActions(ride, job, failure, handlers));
    if (job.error) {
      parts.push(h("details", { class: "technical" }, h("summary", {}, "Technical detail"),
        h("p", { class: "hint" }, job.error)));
    }
  }
  if (job.note && (job.status === "queued" || job.status === "running")) {
    parts.push(h("p", { class: "job-note", role: "status", "data-job-note": "" }, `This job is ${job.note}.`));
  }
  slot.replaceChildren(...parts);
}

/**
 * The ride's newest job (any kind), or null.
 * @param {number} rideId
 * @param {number | null | undefined} knownId the job followed already
 * @returns {Promise<JobOut | null>}
 */
export async function newestJob(rideId, knownId) {
  if (knownId) return get(`/api/jobs/${knownId}`);
  /** @type {import("./api-types").Page_JobOut_} */
  const answer = await get("/api/jobs", { params: { ride_id: rideId, limit: 5, sort: "-id" } });
  return (answer.items || [])[0] ?? null;
}
