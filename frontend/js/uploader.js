// Resumable uploads (the server's tus-like /api/uploads): create, send the bytes the way the server says
// (`transport`): "stream", chunks with Upload-Offset to the API; "s3-parts", parts PUT straight to the
// object store with URLs the API signs. Resume after a dropped connection or a reload from what the
// server has (its offset, or the parts that arrived), then finalize.

import { ApiError, del, get, post, request } from "./api.js";

/** @typedef {Omit<import("./api-types").UploadCreate, "length_bytes" | "filename">} UploadTarget where the file goes */
/** @typedef {"stream" | "s3-parts"} Transport how the bytes go: through the API, or straight to the store */
/**
 * What GET /api/uploads/{id}/parts answers: the parts the store has (a direct upload), or none (a streamed one).
 * @typedef {import("./api-types").StreamedPartsOut | import("./api-types").DirectPartsOut} PartsState
 */
/**
 * An upload being sent: its id, where the server's copy ends, where this browser keeps its id, and how
 * its bytes go.
 * @typedef {object} OpenUpload
 * @property {string} id
 * @property {number} offset
 * @property {string} key
 * @property {Transport} [transport]
 * @property {number | null} [part_bytes]
 * @property {number | null} [parts_total]
 * @property {{number: number, size: number}[]} [parts]
 */
/**
 * What POST /api/uploads/{id}/finalize answers: a clip's recording, or a bundle's ride, and the job it started.
 * @typedef {import("./api-types").ClipFinalisedOut | import("./api-types").BundleFinalisedOut} Finalized
 */
/**
 * @typedef {object} SendOptions
 * @property {(sentBytes: number) => void} [onProgress]
 * @property {AbortSignal} [signal]
 */

const CHUNK_BYTES = 4 * 1024 * 1024;
const RETRIES = 4;
const RESUME_PREFIX = "saddlescope.upload:";

/**
 * @param {File} file
 * @param {UploadTarget} target
 */
function resumeKey(file, target) {
  const where = [target.target, target.ride_id, target.rig_id, target.clip_kind, target.camera].join("/");
  return `${RESUME_PREFIX}${where}:${file.name}:${file.size}:${file.lastModified}`;
}

/**
 * @param {Headers | null | undefined} headers
 * @param {number} fallback
 */
function offsetFrom(headers, fallback) {
  const value = headers?.get("Upload-Offset");
  const n = value === null || value === undefined ? Number.NaN : Number.parseInt(value, 10);
  return Number.isFinite(n) ? n : fallback;
}

/**
 * Where the server's copy ends (UploadOut.offset_bytes).
 * @param {{offset_bytes?: number} | null | undefined} state
 */
function serverOffset(state) {
  return Number(state?.offset_bytes) || 0;
}

/** @type {(ms: number, signal?: AbortSignal) => Promise<void>} */
const sleep = (ms, signal) => new Promise((resolve, reject) => {
  const timer = window.setTimeout(resolve, ms);
  signal?.addEventListener("abort", () => { window.clearTimeout(timer); reject(new DOMException("Aborted", "AbortError")); });
});

/**
 * @param {File} file
 * @param {UploadTarget} target
 * @returns {Promise<OpenUpload>}
 */
async function openUpload(file, target) {
  const key = resumeKey(file, target);
  const known = window.localStorage.getItem(key);
  if (known) {
    try {
      /** @type {import("./api-types").UploadOut | null} */
      const state = await get(`/api/uploads/${known}`);
      if (state && Number(state.length_bytes) === file.size) {
        /** @type {PartsState | null} */
        const parts = await get(`/api/uploads/${known}/parts`);
        return { id: state.id ?? known, offset: serverOffset(parts ?? state), key, ...parts };
      }
    } catch (error) {
      if (!(error instanceof ApiError) || error.status >= 500 || error.status === 0) throw error;
      // 404/410: the server forgot it; start again.
    }
    window.localStorage.removeItem(key);
  }
  /** @type {import("./api-types").UploadCreate} */
  const asked = { ...target, length_bytes: file.size, filename: file.name };
  /** @type {import("./api-types").UploadCreatedOut} */
  const created = await post("/api/uploads", asked);
  window.localStorage.setItem(key, String(created.id));
  return { id: created.id, offset: serverOffset(created), key, transport: created.transport,
    part_bytes: created.part_bytes, parts_total: created.parts_total, parts: [] };
}

/** @param {OpenUpload} upload a direct ("s3-parts") upload: the size of its parts */
function partBytes(upload) {
  return /** @type {number} */ (upload.part_bytes);
}

/**
 * PUT part `number` of `file` to the object store, at a URL the API signs for it.
 * @param {OpenUpload} upload
 * @param {File} file
 * @param {number} number
 * @param {AbortSignal} [signal]
 */
async function sendPart(upload, file, number, signal) {
  /** @type {import("./api-types").PartUrlsOut} */
  const { urls } = await post(`/api/uploads/${upload.id}/parts`, { numbers: [number] }, { signal });
  const start = (number - 1) * partBytes(upload);
  let response;
  try {
    response = await fetch(urls[String(number)], { method: "PUT", body: file.slice(start, start + partBytes(upload)), signal });
  } catch (error) {
    if (error instanceof Error && error.name === "AbortError") throw error;
    throw new ApiError(0, `Cannot reach the file store (${error instanceof Error ? error.message : error}).`, null);
  }
  if (!response.ok) throw new ApiError(response.status >= 500 ? response.status : 0, `The file store refused part ${number} (${response.status}).`, null);
}

/**
 * Send the parts the store does not have yet; a part that fails is retried (a fresh URL each time).
 * @param {OpenUpload} upload
 * @param {File} file
 * @param {SendOptions} options
 */
async function sendParts(upload, file, { onProgress, signal }) {
  const have = new Set((upload.parts || []).map((part) => part.number));
  let sent = (upload.parts || []).reduce((sum, part) => sum + part.size, 0);
  onProgress?.(sent);
  for (let number = 1; number <= (upload.parts_total ?? 0); number += 1) {
    if (have.has(number)) continue;
    for (let failures = 0; ; failures += 1) {
      try {
        await sendPart(upload, file, number, signal);
        break;
      } catch (error) {
        const transient = error instanceof ApiError && (error.status === 0 || error.status >= 500);
        if (!transient || failures >= RETRIES || signal?.aborted) throw error;
        await sleep(500 * 2 ** (failures + 1), signal);
      }
    }
    sent += Math.min(partBytes(upload), file.size - (number - 1) * partBytes(upload));
    onProgress?.(sent);
  }
}

/**
 * @param {string} id
 * @param {File} file
 * @param {number} offset
 * @param {AbortSignal} [signal]
 * @returns {Promise<number>} where the server's copy ends now
 */
async function sendChunk(id, file, offset, signal) {
  const chunk = file.slice(offset, Math.min(offset + CHUNK_BYTES, file.size));
  try {
    const answer = await request("PATCH", `/api/uploads/${id}`, {
      body: chunk,
      headers: { "Upload-Offset": String(offset), "Content-Type": "application/offset+octet-stream" },
      signal,
      withHeaders: true,
    });
    return offsetFrom(answer.headers, offset + chunk.size);
  } catch (error) {
    // 409: our offset is not the server's; carry on from the server's (its Upload-Offset header and
    // `offset_bytes`; neither when the upload takes no more bytes).
    if (error instanceof ApiError && error.status === 409) {
      /** @type {import("./api-types").OffsetConflictOut | null} */
      const conflict = error.body;
      const server = offsetFrom(error.headers, conflict?.offset_bytes ?? Number.NaN);
      if (Number.isFinite(server)) return server;
    }
    throw error;
  }
}

/**
 * @overload
 * @param {File} file
 * @param {UploadTarget} target
 * @param {SendOptions & {finalize: false, body?: object}} options
 * @returns {Promise<{id: string, key: string}>} the complete upload, to finish with finalizeUpload
 */
/**
 * @overload
 * @param {File} file
 * @param {UploadTarget} target
 * @param {SendOptions & {finalize?: true, body?: object}} [options]
 * @returns {Promise<Finalized>}
 */
/**
 * Upload `file` to `target` ({target: "bundle"|"ride_clip"|"rig_clip", ride_id?, rig_id?, clip_kind?, camera?}).
 * `onProgress(sentBytes)` after each chunk. Resolves to the finalize answer (with `finalize: false`: to
 * the complete, not yet finalised upload {id, key}; finish it with `finalizeUpload`).
 * @param {File} file
 * @param {UploadTarget} target
 * @param {SendOptions & {finalize?: boolean, body?: object}} [options]
 * @returns {Promise<Finalized | {id: string, key: string}>}
 */
export async function uploadResumable(file, target, { onProgress, signal, finalize = true, body = {} } = {}) {
  const upload = await openUpload(file, target);
  if (upload.transport === "s3-parts") {
    await sendParts(upload, file, { onProgress, signal });
    if (!finalize) return { id: upload.id, key: upload.key };
    return finalizeUpload(upload, body, { signal });
  }
  let offset = upload.offset;
  onProgress?.(offset);
  let failures = 0;
  while (offset < file.size) {
    try {
      offset = await sendChunk(upload.id, file, offset, signal);
      failures = 0;
      onProgress?.(offset);
    } catch (error) {
      const transient = error instanceof ApiError && (error.status === 0 || error.status >= 500);
      if (!transient || failures >= RETRIES || signal?.aborted) throw error;
      failures += 1;
      await sleep(500 * 2 ** failures, signal);
      /** @type {import("./api-types").UploadOut} */
      const state = await get(`/api/uploads/${upload.id}`);
      offset = serverOffset(state);
    }
  }
  if (!finalize) return { id: upload.id, key: upload.key };
  return finalizeUpload(upload, body, { signal });
}

/**
 * Finalise a complete upload ({id, key} from `uploadResumable(..., {finalize: false})`) with `body`
 * (a bundle: the ride's horse_id, rider_id, gait, direction, ridden_on, notes as the user confirmed them).
 * @param {{id: string, key: string}} upload
 * @param {object} [body]
 * @param {{signal?: AbortSignal}} [options]
 * @returns {Promise<Finalized>}
 */
export async function finalizeUpload(upload, body = {}, { signal } = {}) {
  try {
    /** @type {Finalized} */
    const result = await post(`/api/uploads/${upload.id}/finalize`, body, { signal });
    window.localStorage.removeItem(upload.key);
    return result;
  } catch (error) {
    // A rejected file (4xx) will not get better by resuming: forget it on both sides.
    if (error instanceof ApiError && error.status >= 400 && error.status < 500) {
      window.localStorage.removeItem(upload.key);
      // clips already a ride of the club (409 naming it): the server dropped the upload itself
      if (!Number.isInteger(error.body?.ride_id)) del(`/api/uploads/${upload.id}`).catch(() => {});
    }
    throw error;
  }
}

/**
 * Abandon an upload on the server (the Cancel button).
 * @param {File} file
 * @param {UploadTarget} target
 */
export async function abandonUploads(file, target) {
  const key = resumeKey(file, target);
  const known = window.localStorage.getItem(key);
  window.localStorage.removeItem(key);
  if (known) await del(`/api/uploads/${known}`).catch(() => {});
}
