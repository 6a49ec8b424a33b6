// The REST client: JSON in and out, the session cookie, the CSRF header on unsafe requests, and the
// server's own error reason (FastAPI's `detail`) kept verbatim so pages can show it to the user.

const UNSAFE = new Set(["POST", "PUT", "PATCH", "DELETE"]);
// The names the server uses (saddlescope.api.deps.CSRF_HEADER, CSRF_COOKIE): it sets this one cookie only.
const CSRF_HEADER = "X-CSRF-Token";
const CSRF_COOKIE = "saddlescope_csrf";

/** @type {string | null} */
let csrfToken = null;
/** @type {Set<() => void>} */
const unauthorisedListeners = new Set();

/**
 * @typedef {object} RequestOptions
 * @property {unknown} [json] sent as the JSON body
 * @property {BodyInit} [body] sent as is (FormData, Blob)
 * @property {HeadersInit} [headers]
 * @property {AbortSignal} [signal]
 * @property {Record<string, string | number | boolean | null | undefined>} [params] query parameters (empty ones left out)
 * @property {boolean} [withHeaders] resolve to {data, headers, status} instead of the body
 */

/**
 * A list answer (saddlescope.api.schemas.Page): a page of rows and how many match in all.
 * @template T
 * @typedef {object} Page
 * @property {T[]} items
 * @property {number} total
 * @property {number} limit
 * @property {number} offset
 */

/** An HTTP error with the server's reason (`detail`) as its message. */
export class ApiError extends Error {
  /**
   * @param {number} status the HTTP status (0: the server was not reached)
   * @param {string} message the server's reason
   * @param {any} body the parsed answer (any: an error's body is the route's own, read where it is known)
   */
  constructor(status, message, body) {
    super(message);
    this.name = "ApiError";
    this.status = status;
    this.body = body;
    /** @type {Headers | null} the answer's headers (Upload-Offset of a 409) */
    this.headers = null;
  }
}

/**
 * Remember the CSRF token a login, registration or /me answer handed out.
 * @param {string | null | undefined} token
 */
export function setCsrfToken(token) {
  csrfToken = token || null;
}

function csrfFromCookie() {
  for (const part of document.cookie.split(";")) {
    const [name, ...rest] = part.trim().split("=");
    if (name === CSRF_COOKIE) return decodeURIComponent(rest.join("="));
  }
  return null;
}

/**
 * Called with no arguments whenever the server answers 401 (the session expired or never was).
 * @param {() => void} listener
 * @returns {() => boolean} to stop listening
 */
export function onUnauthorised(listener) {
  unauthorisedListeners.add(listener);
  return () => unauthorisedListeners.delete(listener);
}

/**
 * FastAPI `detail` as one readable sentence: a string as is, validation errors as "field: message".
 * @param {any} body the parsed answer (any: FastAPI's {detail}, a string, or anything a proxy sent)
 * @param {number} status
 * @param {string} [statusText]
 * @returns {string}
 */
function reasonOf(body, status, statusText) {
  const detail = body && typeof body === "object" ? body.detail : null;
  if (typeof detail === "string" && detail) return detail;
  if (Array.isArray(detail) && detail.length) {
    return detail.map((/** @type {{loc?: unknown[], msg?: string}} */ item) => {
      const loc = Array.isArray(item.loc) ? item.loc.filter((p) => p !== "body" && p !== "query").join(".") : "";
      return loc ? `${loc}: ${item.msg}` : String(item.msg ?? JSON.stringify(item));
    }).join("; ");
  }
  if (detail && typeof detail === "object") return JSON.stringify(detail);
  if (typeof body === "string" && body.trim() && body.length < 500) return body.trim();
  return `${status} ${statusText || "error"}`.trim();
}

/**
 * @param {string} method
 * @param {HeadersInit | undefined} extra
 * @param {boolean} hasJson
 */
function headersFor(method, extra, hasJson) {
  const headers = new Headers(extra || {});
  if (!headers.has("Accept")) headers.set("Accept", "application/json");
  if (hasJson) headers.set("Content-Type", "application/json");
  if (UNSAFE.has(method)) {
    // The cookie is the source of truth (a later sign-in in another tab replaces it).
    const token = csrfFromCookie() || csrfToken;
    if (token) headers.set(CSRF_HEADER, token);
  }
  return headers;
}

/** @param {Response} response */
async function readBody(response) {
  if (response.status === 204) return null;
  const type = response.headers.get("Content-Type") || "";
  if (type.includes("json")) {
    try {
      return await response.json();
    } catch {
      return null;
    }
  }
  return response.text();
}

/**
 * One request. `json` is sent as a JSON body; `body` (FormData, Blob) as is.
 * Resolves to the parsed body (with `withHeaders`: {data, headers, status});
 * rejects with ApiError (status and the server's reason).
 * @param {string} method
 * @param {string} url
 * @param {RequestOptions} [options]
 * @returns {Promise<any>} any: get, post, patch and del hand it on as the type their caller names
 */
export async function request(method, url, { json, body, headers, signal, params, withHeaders = false } = {}) {
  method = method.toUpperCase();
  const target = new URL(url, window.location.origin);
  for (const [key, value] of Object.entries(params || {})) {
    if (value !== undefined && value !== null && value !== "") target.searchParams.set(key, String(value));
  }
  let response;
  try {
    response = await fetch(target, {
      method,
      credentials: "same-origin",
      headers: headersFor(method, headers, json !== undefined),
      body: json !== undefined ? JSON.stringify(json) : body,
      signal,
    });
  } catch (error) {
    if (error instanceof Error && error.name === "AbortError") throw error;
    throw new ApiError(0, `Cannot reach the server (${error instanceof Error ? error.message : error}).`, null);
  }
  const parsed = await readBody(response);
  if (!response.ok) {
    if (response.status === 401) for (const listener of unauthorisedListeners) listener();
    const error = new ApiError(response.status, reasonOf(parsed, response.status, response.statusText), parsed);
    error.headers = response.headers;
    throw error;
  }
  return withHeaders ? { data: parsed, headers: response.headers, status: response.status } : parsed;
}

// The answer is of the type the caller names (/** @type {import("./api-types").RideOut} */ const ride =
// await get(...)): TypeScript infers T from it; a caller that names none gets `unknown`, which it cannot
// read without saying what it is.
/** @type {<T = unknown>(url: string, options?: RequestOptions) => Promise<T>} */
export const get = (url, options) => request("GET", url, options);
/** @type {<T = unknown>(url: string, json?: unknown, options?: RequestOptions) => Promise<T>} */
export const post = (url, json, options) => request("POST", url, { ...options, json });
/** @type {<T = unknown>(url: string, json?: unknown, options?: RequestOptions) => Promise<T>} */
export const patch = (url, json, options) => request("PATCH", url, { ...options, json });
/** @type {<T = unknown>(url: string, options?: RequestOptions) => Promise<T>} */
export const del = (url, options) => request("DELETE", url, options);

/**
 * A list answer may be a bare array or a page object ({items: [...]}); pages want the array.
 * @template T the rows' type
 * @param {T[] | {items?: T[]} | null | undefined} answer
 * @returns {T[]}
 */
export function itemsOf(answer) {
  if (Array.isArray(answer)) return answer;
  if (answer && Array.isArray(answer.items)) return answer.items;
  return [];
}

// The most rows a list answers at once (the `limit` bound of saddlescope.api.routers.common's Paging).
export const MAX_PAGE_ROWS = 500;

/**
 * Every row of a paged list (GET `path` answering {items, total, limit, offset}), for pickers that must
 * offer all of a club's horses, not its first 500: the first page says the total, the rest are read
 * together.
 * @template [T=unknown] the rows' type (the list's schema, e.g. HorseOut)
 * @param {string} path
 * @param {RequestOptions["params"]} [params] the list's filters and sort
 * @param {RequestOptions} [options]
 * @returns {Promise<T[]>}
 */
export async function getAll(path, params = {}, options = {}) {
  /** @type {(offset: number) => Promise<Page<T>>} */
  const pageAt = (offset) => get(path, { ...options, params: { ...params, limit: MAX_PAGE_ROWS, offset } });
  const first = await pageAt(0);
  const offsets = [];
  for (let offset = first.items.length; first.items.length && offset < first.total; offset += MAX_PAGE_ROWS) {
    offsets.push(offset);
  }
  const rest = await Promise.all(offsets.map(pageAt));
  return [first, ...rest].flatMap((page) => page.items);
}
