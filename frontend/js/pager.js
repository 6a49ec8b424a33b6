// A list's state in the URL hash query (#/rides?horse_id=3&page=2&sort=-ridden_on) and its pager
// (previous / next, "Rows 51–100 of 10,000", rows per page). Reload, back and forward keep the state
// because the page is drawn from the URL: every change is a navigation.

import { h } from "./dom.js";
import { currentPath, navigate } from "./router.js";

/**
 * A list's state, read from the URL.
 * @typedef {object} ListState
 * @property {Record<string, string>} filters the filters' values ("" when not given)
 * @property {number} page 1-based
 * @property {number} size rows per page
 * @property {string} sort a field name, "-field" for descending
 * @property {URLSearchParams} query
 */
/** @typedef {Record<string, string | number>} ListParams a list's query parameters of the API */

const PAGE_SIZES = [25, 50, 100, 200];
const DEFAULT_SIZE = 50;

/**
 * The list state of the current URL: `filters` (the names given, "" when absent), the page (1-based),
 * rows per page and sort (the given default when absent).
 * @param {URLSearchParams} query
 * @param {{filters?: string[], sort?: string}} [defaults]
 * @returns {ListState}
 */
export function listState(query, { filters = [], sort = "" } = {}) {
  const size = Number.parseInt(query.get("size") ?? "", 10);
  const pageNo = Number.parseInt(query.get("page") ?? "", 10);
  return {
    filters: Object.fromEntries(filters.map((name) => [name, query.get(name) ?? ""])),
    page: Number.isFinite(pageNo) && pageNo > 0 ? pageNo : 1,
    size: PAGE_SIZES.includes(size) ? size : DEFAULT_SIZE,
    sort: query.get("sort") || sort,
    query,
  };
}

/**
 * The API parameters of a list state: the filters given, limit, offset and sort.
 * @param {ListState} state
 * @returns {ListParams}
 */
export function apiParams(state) {
  /** @type {ListParams} */
  const params = { limit: state.size, offset: (state.page - 1) * state.size };
  if (state.sort) params.sort = state.sort;
  for (const [name, value] of Object.entries(state.filters)) if (value !== "") params[name] = value;
  return params;
}

/**
 * Go to the same page with `changes` to its query (null or "" removes a key); a new history entry.
 * @param {Record<string, string | number | null | undefined>} changes
 */
export function updateQuery(changes) {
  const { path, query } = currentPath();
  const next = new URLSearchParams(query);
  for (const [key, value] of Object.entries(changes)) {
    if (value === null || value === undefined || value === "") next.delete(key);
    else next.set(key, String(value));
  }
  const text = next.toString();
  navigate(text ? `${path}?${text}` : path);
}

/**
 * A filter form's field `name` (an input, a select or a group of radio buttons), or null where the form
 * has none.
 * @param {HTMLFormElement} form
 * @param {string} name
 * @returns {HTMLInputElement | HTMLSelectElement | RadioNodeList | null}
 */
function filterField(form, name) {
  const el = form.elements.namedItem(name);
  return el instanceof HTMLInputElement || el instanceof HTMLSelectElement || el instanceof RadioNodeList ? el : null;
}

/**
 * Fill a filter form's fields from the state, and make submitting it (and "Clear") update the URL.
 * @param {HTMLFormElement} form
 * @param {ListState} state
 */
export function bindFilterForm(form, state) {
  for (const [name, value] of Object.entries(state.filters)) {
    const el = filterField(form, name);
    if (el) el.value = value;
  }
  const sort = filterField(form, "sort");
  if (sort && state.sort) sort.value = state.sort;
  form.addEventListener("submit", (event) => {
    event.preventDefault();
    /** @type {Record<string, string | null>} */
    const changes = { page: null };
    for (const name of Object.keys(state.filters)) changes[name] = filterField(form, name)?.value.trim() ?? "";
    if (sort) changes.sort = sort.value;
    updateQuery(changes);
  });
  const clear = form.querySelector("[data-filter-clear]");
  clear?.addEventListener("click", () => {
    updateQuery({ ...Object.fromEntries(Object.keys(state.filters).map((name) => [name, null])), page: null });
  });
  // A select or date changes the list at once; text fields wait for Enter or "Show".
  for (const el of form.querySelectorAll("select, input[type=date]")) {
    el.addEventListener("change", () => form.requestSubmit());
  }
}

const number = new Intl.NumberFormat("en-GB");

/**
 * A pager for a list `page` answer ({total, limit, offset}) with the state of the URL.
 * @param {{total?: number, offset: number, items?: unknown[]}} answer a Page of the API
 * @param {ListState} state
 * @param {{noun?: string}} [words]
 */
export function pager(answer, state, { noun = "rows" } = {}) {
  const total = answer.total ?? 0;
  const first = total ? answer.offset + 1 : 0;
  const last = Math.min(answer.offset + (answer.items?.length ?? 0), total);
  const pages = Math.max(1, Math.ceil(total / state.size));
  const sizeSelect = h("select", { "aria-label": `${noun} per page`, "data-pager-size": true,
                                   onchange: (event) => updateQuery({ size: /** @type {HTMLSelectElement} */ (event.target).value, page: null }) },
    PAGE_SIZES.map((n) => h("option", { value: n, selected: n === state.size }, `${n} per page`)));
  return h("nav", { class: "pager", "aria-label": `Pages of ${noun}`, "data-pager": true },
    h("button", { type: "button", "data-pager-prev": true, disabled: state.page <= 1,
                  onclick: () => updateQuery({ page: state.page - 1 > 1 ? state.page - 1 : null }) },
      "\u2039 Previous"),
    h("span", { class: "pager-range", "data-pager-range": true, "aria-live": "polite" },
      total ? `${capitalised(noun)} ${number.format(first)}\u2013${number.format(last)} of ${number.format(total)}`
        : `No ${noun}`,
      pages > 1 ? ` (page ${number.format(state.page)} of ${number.format(pages)})` : ""),
    h("button", { type: "button", "data-pager-next": true, disabled: state.page >= pages,
                  onclick: () => updateQuery({ page: state.page + 1 }) }, "Next \u203a"),
    sizeSelect);
}

/** @param {string} word */
function capitalised(word) {
  return word[0].toUpperCase() + word.slice(1);
}
