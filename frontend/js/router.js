// Hash routes ("#/rides/12") to page modules; each page gets a fresh copy of its <template>.

import { loadMarkup } from "./markup.js";

/**
 * A page: fills `view` (a fresh root) for the route's `params` (":id" of the pattern) and the hash's query;
 * may return (or resolve to) a cleanup function, run when the page is left.
 * `load`, when given (app.js's lazy pages), fetches the page's module, asked for beside its markup.
 * @typedef {((view: HTMLElement, params: Record<string, string>, query: URLSearchParams) => unknown)
 *   & {load?: () => Promise<unknown>}} Mount
 */
/**
 * @typedef {object} Route
 * @property {RegExp} regex
 * @property {string[]} names the pattern's parameters, in order
 * @property {Mount} mount
 * @property {string | undefined} title
 * @property {boolean} auth whether the page needs a signed-in user
 * @property {string[]} markup the files of the templates the page uses (js/markup.js)
 */
/**
 * What render() draws into and with: `guard(route, path)` may answer another path to go to instead.
 * @typedef {object} RenderOptions
 * @property {HTMLElement} view
 * @property {(route: Route, path: string) => string | null} [guard]
 * @property {Mount} notFound
 */

/** @type {Route[]} */
const routes = [];
/** @type {(() => void) | null} */
let cleanup = null;
let renderCount = 0;

/**
 * Register a page: pattern like "/rides/:id", and `mount(view, params, query)` that may return a cleanup.
 * `markup`: the files of the templates the page uses (js/markup.js), in the document before `mount` runs;
 * `mount.load`, when given (app.js's lazy pages), fetches the page's module, asked for beside them.
 * @param {string} pattern
 * @param {Mount} mount
 * @param {{title?: string, auth?: boolean, markup?: string[]}} [options]
 */
export function route(pattern, mount, { title, auth = true, markup = [] } = {}) {
  /** @type {string[]} */
  const names = [];
  const regex = new RegExp(`^${pattern.replace(/:(\w+)/g, (_, name) => {
    names.push(name);
    return "([^/]+)";
  })}/?$`);
  routes.push({ regex, names, mount, title, auth, markup });
}

export function currentPath() {
  const hash = window.location.hash.replace(/^#/, "") || "/";
  const [path, queryString] = hash.split("?");
  return { path: path || "/", query: new URLSearchParams(queryString || "") };
}

/** @param {string} path */
export function navigate(path) {
  if (window.location.hash === `#${path}`) render();
  else window.location.hash = path;
}

/** @param {string} path */
function match(path) {
  for (const r of routes) {
    const m = r.regex.exec(path);
    if (m) return { route: r, params: Object.fromEntries(r.names.map((name, i) => [name, decodeURIComponent(m[i + 1])])) };
  }
  return null;
}

/**
 * Render the page for the current hash into `view`. `guard(route)` may return another path to go to
 * (e.g. the sign-in page) instead.
 * @param {RenderOptions} [options] the first call's, kept for later calls
 */
export async function render({ view, guard, notFound } = renderOptions) {
  renderOptions = { view, guard, notFound };
  const { path, query } = currentPath();
  const found = match(path);
  const redirect = guard && found ? guard(found.route, path) : null;
  if (redirect && redirect !== path) {
    navigate(redirect);
    return;
  }
  if (cleanup) {
    try { cleanup(); } catch (error) { console.warn("page cleanup failed", error); }
    cleanup = null;
  }
  const count = ++renderCount;
  // The page's markup and its module are asked for at once, as the route matches (neither waits on the other).
  const ready = found ? Promise.all([loadMarkup(found.route.markup), found.route.mount.load?.()]) : null;
  // Each render mounts into a root of its own: a slower, older mount that finishes late then fills a
  // detached root instead of appending a second copy of a page to the view.
  const root = document.createElement("div");
  root.className = "page-root";
  view.replaceChildren(root);
  view.setAttribute("aria-busy", "true");
  markNav(path);
  const mount = found ? found.route.mount : notFound;
  document.title = found?.route.title ? `${found.route.title} \u2013 SaddleScope` : "SaddleScope";
  try {
    await ready;
    const result = await mount(root, found ? found.params : {}, query);
    if (count !== renderCount) {
      if (typeof result === "function") result(); // a newer page was rendered meanwhile
      return;
    }
    cleanup = typeof result === "function" ? /** @type {() => void} */ (result) : null;
  } finally {
    if (count === renderCount) view.removeAttribute("aria-busy");
  }
  // Move focus to the new page's heading, as a page load would, for keyboard and screen-reader users
  // (not on the first page, where the browser's own start is right).
  const heading = view.querySelector("h1");
  if (heading && count > 1) {
    heading.setAttribute("tabindex", "-1");
    heading.focus({ preventScroll: true });
  }
}
/** @type {RenderOptions} set by the first render */
let renderOptions = /** @type {RenderOptions} */ ({});

/** @param {string} path */
function markNav(path) {
  for (const link of document.querySelectorAll("[data-nav] a")) {
    const target = (link.getAttribute("href") ?? "").replace(/^#/, "");
    const active = target === "/" ? path === "/" : path === target || path.startsWith(`${target}/`);
    if (active) link.setAttribute("aria-current", "page");
    else link.removeAttribute("aria-current");
  }
}
