// @ts-check
// Each page's markup lives beside its module (js/views/ride.html beside ride.js), a part shared by several
// pages beside the module that fills it (js/ride-edit.html): files of <template id="page-NAME"> and
// <template id="part-NAME"> elements. A route names the files its page needs (app.js); the router fetches
// them as the route matches, beside the page's module, and mounts the page once their templates are in the
// document, where dom.js's page() finds them. Each file is fetched once (a second ask waits on the first);
// the browser revalidates it as it does the modules (no-cache, answered 304 by its ETag).

/** @type {Map<string, Promise<void>>} a file's path -> its templates in the document */
const files = new Map();

/**
 * Bring the templates of `paths` (relative to the document, e.g. "js/views/ride.html") into the document.
 * @param {readonly string[]} paths
 * @returns {Promise<void>}
 */
export async function loadMarkup(paths) {
  await Promise.all(paths.map((path) => {
    let loading = files.get(path);
    if (!loading) {
      loading = addTemplates(path);
      files.set(path, loading);
      loading.catch(() => files.delete(path)); // failed (offline, a deploy in between): asked again next time
    }
    return loading;
  }));
}

/** @param {string} path */
async function addTemplates(path) {
  const response = await fetch(path);
  if (!response.ok) throw new Error(`cannot load the page's markup ${path}: HTTP ${response.status}`);
  // Parsed as an inert document (nothing in a template runs or loads), then its templates moved here.
  const parsed = new DOMParser().parseFromString(await response.text(), "text/html");
  const templates = [...parsed.querySelectorAll("template")];
  if (!templates.length) throw new Error(`the page's markup ${path} holds no <template>`);
  document.body.append(...templates);
}
