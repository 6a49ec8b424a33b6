// Small DOM helpers shared by the pages: build elements, clone page templates, announce, show errors.

/** Create an element: h("td", {class: "num"}, "1.23"). Attributes starting with "on" are listeners. */
export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs || {})) {
    if (value === undefined || value === null || value === false) continue;
    if (key.startsWith("on") && typeof value === "function") el.addEventListener(key.slice(2), value);
    else if (key === "class") el.className = value;
    else if (key === "dataset") Object.assign(el.dataset, value);
    else if (key === "html") el.innerHTML = value; // only ever used with our own constant markup
    else el.setAttribute(key, value === true ? "" : value);
  }
  for (const child of children.flat()) {
    if (child === undefined || child === null || child === false) continue;
    el.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return el;
}

/** Replace `el`'s children, skipping absent parts (null / undefined / false), as h() does: the DOM's own
 *  replaceChildren would show them as the words "null" or "undefined". */
export function fill(el, ...children) {
  el.replaceChildren(...children.flat().filter((c) => c !== undefined && c !== null && c !== false));
  return el;
}

/** A fresh copy of <template id="page-NAME">, its shared parts filled in. */
export function page(name) {
  const template = document.getElementById(`page-${name}`);
  if (!template) throw new Error(`no template page-${name}`);
  const copy = template.content.cloneNode(true);
  fillParts(copy);
  return copy;
}

// Markup several forms share lives once, in <template id="part-NAME">: each placeholder
// <div data-part="NAME" data-id-prefix="P"> is replaced by a copy whose "PART-" ids start with P.
function fillParts(root) {
  for (const slot of root.querySelectorAll("[data-part]")) {
    const template = document.getElementById(`part-${slot.dataset.part}`);
    if (!template) throw new Error(`no template part-${slot.dataset.part}`);
    const part = template.content.cloneNode(true);
    for (const el of part.querySelectorAll("[id], [for], [aria-describedby]")) {
      for (const attr of ["id", "for", "aria-describedby"]) {
        const value = el.getAttribute(attr);
        if (value) el.setAttribute(attr, value.replaceAll("PART-", `${slot.dataset.idPrefix}-`));
      }
    }
    slot.replaceWith(part);
  }
}

/** Say something to screen-reader users without moving focus. */
export function announce(message) {
  const region = document.querySelector("[data-announcer]");
  if (!region) return;
  region.textContent = "";
  // A new text node after a tick makes screen readers repeat an identical message.
  window.setTimeout(() => { region.textContent = message; }, 30);
}

/** Show (or with null, hide) the error paragraph of a form or section; returns the element. */
export function showError(scope, error) {
  const el = scope.querySelector("[data-form-error]");
  if (!el) return null;
  if (!error) {
    el.hidden = true;
    el.textContent = "";
    return el;
  }
  el.textContent = typeof error === "string" ? error : error.message;
  el.hidden = false;
  return el;
}

/** A form's fields as an object; empty fields are left out, data-kind="int|float" are numbers. */
export function formValues(form) {
  const values = {};
  for (const el of form.elements) {
    if (!el.name || el.disabled || el.type === "file" || el.type === "submit" || el.type === "button") continue;
    if ((el.type === "radio" || el.type === "checkbox") && !el.checked) continue;
    const raw = el.value.trim();
    if (raw === "") continue;
    const kind = el.dataset.kind;
    values[el.name] = kind === "int" ? Number.parseInt(raw, 10) : kind === "float" ? Number.parseFloat(raw) : raw;
  }
  return values;
}

/** Disable a form's buttons while `work` runs, and re-enable them after. */
export async function busy(form, work) {
  const buttons = [...form.querySelectorAll("button")];
  buttons.forEach((b) => { b.disabled = true; });
  form.setAttribute("aria-busy", "true");
  try {
    return await work();
  } finally {
    buttons.forEach((b) => { b.disabled = false; });
    form.removeAttribute("aria-busy");
  }
}

export function formatDate(value) {
  if (!value) return "";
  const date = new Date(value);
  if (Number.isNaN(date.getTime())) return String(value);
  return date.toISOString().slice(0, 16).replace("T", " ");
}

/** Copy a text field's value to the clipboard; true when copied (else the text is left selected). */
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
