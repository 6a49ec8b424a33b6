// Small DOM helpers shared by the pages: build elements, clone page templates, announce, show errors.

/**
 * What h() and fill() put in an element: nodes and text (numbers too), or lists of them (one level deep);
 * null, undefined and false are left out.
 * @typedef {Node | string | number | boolean | null | undefined} Part
 * @typedef {Part | Part[]} Child
 */
/** @typedef {((event: Event) => unknown) | null | undefined | false} Listener */
/**
 * h()'s attributes: "class", "dataset" (an object), "html" (our own constant markup), `on<event>` listeners
 * (the pages' own named, so their events are typed), and any other attribute (true: present and empty;
 * null, undefined and false: left out).
 * @typedef {{onclick?: Listener, onchange?: Listener, onsubmit?: Listener, oninput?: Listener,
 *   [key: string]: unknown}} Attrs
 */

/**
 * Create an element: h("td", {class: "num"}, "1.23"). Attributes starting with "on" are listeners.
 * @template {keyof HTMLElementTagNameMap} K
 * @param {K} tag
 * @param {Attrs | null} [attrs]
 * @param {...Child} children
 * @returns {HTMLElementTagNameMap[K]}
 */
export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs || {})) {
    if (value === undefined || value === null || value === false) continue;
    if (key.startsWith("on") && typeof value === "function") el.addEventListener(key.slice(2), /** @type {EventListener} */ (value));
    else if (key === "class") el.className = String(value);
    else if (key === "dataset") Object.assign(el.dataset, value);
    else if (key === "html") el.innerHTML = String(value); // only ever used with our own constant markup
    else el.setAttribute(key, value === true ? "" : String(value));
  }
  for (const child of children.flat()) {
    if (child === undefined || child === null || child === false) continue;
    el.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return el;
}

/**
 * Replace `el`'s children, skipping absent parts (null / undefined / false), as h() does: the DOM's own
 * replaceChildren would show them as the words "null" or "undefined".
 * @template {Element} E
 * @param {E} el
 * @param {...Child} children
 * @returns {E}
 */
export function fill(el, ...children) {
  el.replaceChildren(...children.flat().filter((c) => c !== undefined && c !== null && c !== false)
    .map((c) => (c instanceof Node ? c : String(c))));
  return el;
}

// Typed look-ups of a page's own markup (its template's [data-*] hooks and form fields). A hook the page
// needs and does not find is a bug in its template: one() and field() throw, naming it, where the page
// would otherwise fail later on `null`. `type` is the element's class (HTMLElement unless said), checked.

/**
 * An element's class (HTMLInputElement, ...), for the look-ups below.
 * @template T
 * @typedef {abstract new (...args: never[]) => T} ClassOf
 */

/**
 * `type`, or HTMLElement where left out: then T is its default, HTMLElement (TypeScript cannot see that
 * the two agree, hence the cast).
 * @template T
 * @param {ClassOf<T>} [type]
 * @returns {ClassOf<T>}
 */
function classOr(type) {
  return type ?? /** @type {ClassOf<T>} */ (/** @type {unknown} */ (HTMLElement));
}

/**
 * @template T
 * @param {Element | RadioNodeList | null} el
 * @param {string} what the selector, for the error
 * @param {ClassOf<T>} [type]
 * @returns {T}
 */
function ofType(el, what, type) {
  const want = classOr(type);
  if (!(el instanceof want)) throw new Error(el ? `${what} is no ${want.name}` : `no ${what} on the page`);
  return el;
}

/**
 * The element `selector` finds under `root`; it must be there.
 * @template {Element} [T=HTMLElement]
 * @param {ParentNode} root
 * @param {string} selector
 * @param {ClassOf<T>} [type]
 * @returns {T}
 */
export function one(root, selector, type) {
  return ofType(root.querySelector(selector), selector, type);
}

/**
 * The element `selector` finds under `root`, or null where there is none (a hook some pages lack).
 * @template {Element} [T=HTMLElement]
 * @param {ParentNode} root
 * @param {string} selector
 * @param {ClassOf<T>} [type]
 * @returns {T | null}
 */
export function maybeOne(root, selector, type) {
  const el = root.querySelector(selector);
  return el ? ofType(el, selector, type) : null;
}

/**
 * Every element `selector` finds under `root`, as an array.
 * @template {Element} [T=HTMLElement]
 * @param {ParentNode} root
 * @param {string} selector
 * @param {ClassOf<T>} [type]
 * @returns {T[]}
 */
export function all(root, selector, type) {
  return [...root.querySelectorAll(selector)].map((el) => ofType(el, selector, type));
}

/**
 * A form's control named `name` (form.elements[name]): an <input> unless `type` says otherwise
 * (HTMLSelectElement, HTMLTextAreaElement, RadioNodeList for a group of radio buttons).
 * @template {Element | RadioNodeList} [T=HTMLInputElement]
 * @param {HTMLFormElement} form
 * @param {string} name
 * @param {ClassOf<T>} [type]
 * @returns {T}
 */
export function field(form, name, type) {
  const el = form.elements.namedItem(name);
  const want = type ?? /** @type {ClassOf<T>} */ (/** @type {unknown} */ (HTMLInputElement)); // T's default
  if (!(el instanceof want)) throw new Error(el ? `the field ${name} is no ${want.name}` : `no field ${name} in the form`);
  return el;
}

/** @typedef {HTMLInputElement | HTMLSelectElement | HTMLTextAreaElement} Control a field with a value */

/**
 * A form's field `name` with a value: an <input>, a <select> or a <textarea>, or null where it has none.
 * @param {HTMLFormElement} form
 * @param {string} name
 * @returns {Control | null}
 */
export function maybeControl(form, name) {
  const el = form.elements.namedItem(name);
  if (el instanceof HTMLInputElement || el instanceof HTMLSelectElement || el instanceof HTMLTextAreaElement) return el;
  if (el) throw new Error(`the field ${name} is no input, select or textarea`);
  return null;
}

/**
 * A form's field `name` with a value (an <input>, a <select> or a <textarea>); it must be there.
 * @param {HTMLFormElement} form
 * @param {string} name
 * @returns {Control}
 */
export function control(form, name) {
  const el = maybeControl(form, name);
  if (!el) throw new Error(`no field ${name} in the form`);
  return el;
}

/**
 * A fresh copy of <template id="page-NAME">, its shared parts filled in.
 * @param {string} name
 * @returns {DocumentFragment}
 */
export function page(name) {
  const template = /** @type {HTMLTemplateElement | null} */ (document.getElementById(`page-${name}`));
  if (!template) throw new Error(`no template page-${name}`);
  const copy = /** @type {DocumentFragment} */ (template.content.cloneNode(true));
  fillParts(copy);
  return copy;
}

// Markup several forms share lives once, in <template id="part-NAME">: each placeholder
// <div data-part="NAME" data-id-prefix="P"> is replaced by a copy whose "PART-" ids start with P.
/** @param {ParentNode} root */
function fillParts(root) {
  for (const slot of all(root, "[data-part]")) {
    const template = /** @type {HTMLTemplateElement | null} */ (document.getElementById(`part-${slot.dataset.part}`));
    if (!template) throw new Error(`no template part-${slot.dataset.part}`);
    const part = /** @type {DocumentFragment} */ (template.content.cloneNode(true));
    for (const el of part.querySelectorAll("[id], [for], [aria-describedby]")) {
      for (const attr of ["id", "for", "aria-describedby"]) {
        const value = el.getAttribute(attr);
        if (value) el.setAttribute(attr, value.replaceAll("PART-", `${slot.dataset.idPrefix}-`));
      }
    }
    slot.replaceWith(part);
  }
}

/**
 * Say something to screen-reader users without moving focus.
 * @param {string} message
 */
export function announce(message) {
  const region = document.querySelector("[data-announcer]");
  if (!region) return;
  region.textContent = "";
  // A new text node after a tick makes screen readers repeat an identical message.
  window.setTimeout(() => { region.textContent = message; }, 30);
}

/**
 * Show (or with null, hide) the error paragraph of a form or section; returns the element.
 * @param {ParentNode} scope
 * @param {unknown} error an Error (its message is shown), a sentence, or null to hide it
 * @returns {HTMLElement | null}
 */
export function showError(scope, error) {
  const el = maybeOne(scope, "[data-form-error]");
  if (!el) return null;
  if (!error) {
    el.hidden = true;
    el.textContent = "";
    return el;
  }
  el.textContent = typeof error === "string" ? error : messageOf(error);
  el.hidden = false;
  return el;
}

/**
 * The message of what a `catch` caught (an Error, ApiError among them); "" for a thrown thing without one.
 * @param {unknown} error
 * @returns {string}
 */
export function messageOf(error) {
  const message = error && typeof error === "object" && "message" in error ? error.message : undefined;
  return message === undefined || message === null ? "" : String(message);
}

/**
 * A form's fields as an object; empty fields are left out, data-kind="int|float" are numbers.
 * @param {HTMLFormElement} form
 * @returns {Record<string, string | number>}
 */
export function formValues(form) {
  /** @type {Record<string, string | number>} */
  const values = {};
  for (const el of form.elements) {
    // buttons, fieldsets and outputs carry no value of the form's
    if (!(el instanceof HTMLInputElement || el instanceof HTMLSelectElement || el instanceof HTMLTextAreaElement)) continue;
    if (!el.name || el.disabled || el.type === "file" || el.type === "submit" || el.type === "button") continue;
    if (el instanceof HTMLInputElement && (el.type === "radio" || el.type === "checkbox") && !el.checked) continue;
    const raw = el.value.trim();
    if (raw === "") continue;
    const kind = el.dataset.kind;
    values[el.name] = kind === "int" ? Number.parseInt(raw, 10) : kind === "float" ? Number.parseFloat(raw) : raw;
  }
  return values;
}

/**
 * Disable a form's buttons while `work` runs, and re-enable them after.
 * @template T
 * @param {HTMLFormElement} form
 * @param {() => Promise<T> | T} work
 * @returns {Promise<T>}
 */
export async function busy(form, work) {
  const buttons = all(form, "button", HTMLButtonElement);
  buttons.forEach((b) => { b.disabled = true; });
  form.setAttribute("aria-busy", "true");
  try {
    return await work();
  } finally {
    buttons.forEach((b) => { b.disabled = false; });
    form.removeAttribute("aria-busy");
  }
}

/**
 * "2026-03-01 14:05" (UTC) of an ISO time; "" for none, the text as it is when it is no time.
 * @param {string | null | undefined} value
 */
export function formatDate(value) {
  if (!value) return "";
  const date = new Date(value);
  if (Number.isNaN(date.getTime())) return String(value);
  return date.toISOString().slice(0, 16).replace("T", " ");
}

/**
 * Copy a text field's value to the clipboard; true when copied (else the text is left selected).
 * @param {HTMLInputElement | HTMLTextAreaElement} input
 * @returns {Promise<boolean>}
 */
export async function copyText(input) {
  try {
    await navigator.clipboard.writeText(input.value);
    return true;
  } catch {
    // No clipboard permission (plain http, older browsers): select it so Ctrl+C works.
    input.focus();
    input.select();
    return document.execCommand?.("copy") ?? false;
  }
}
