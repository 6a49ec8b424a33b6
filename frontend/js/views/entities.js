// Horses, riders and saddles: a list searched, sorted and paged by the server (state in the URL:
// #/horses?q=bra&page=2), with edit buttons, next to a form that adds or edits one. Delete is for
// admins only (horse.delete, saddle.delete), so nobody else sees it. A horse's name opens its page
// (#/horses/:id), a saddle's its page across horses (#/saddles/:id).

import { del, get, itemsOf, patch, post } from "../api.js";
import { announce, busy, control, formValues, h, maybeControl, one, page, showError } from "../dom.js";
import { fmt } from "../format.js";
import { fillOptions } from "../options.js";
import { apiParams, bindFilterForm, listState, pager } from "../pager.js";
import { saddleTypeText } from "../saddle-words.js";
import { can } from "../session.js";

/** @typedef {import("../api-types").HorseOut | import("../api-types").RiderOut | import("../api-types").SaddleOut} Entity */
/**
 * One kind of list: where it lives, its noun, its table's columns (the first is the row's heading) and its
 * form's fields.
 * @template {Entity} T
 * @typedef {object} Kind
 * @property {string} url
 * @property {string} noun
 * @property {((x: T) => import("../dom.js").Child)[]} columns
 * @property {string[]} fields
 * @property {string} deletePermission
 */

/** @type {{horses: Kind<import("../api-types").HorseOut>, riders: Kind<import("../api-types").RiderOut>, saddles: Kind<import("../api-types").SaddleOut>}} */
const KINDS = {
  horses: {
    url: "/api/horses",
    noun: "horse",
    columns: [(x) => h("a", { href: `#/horses/${x.id}` }, x.name), (x) => x.breed ?? "", (x) => x.birth_year ?? "",
              (x) => (x.height_withers_m ? fmt(x.height_withers_m) : "")],
    fields: ["name", "breed", "birth_year", "height_withers_m"],
    deletePermission: "horse.delete",
  },
  riders: {
    url: "/api/riders",
    noun: "rider",
    columns: [(x) => x.name, (x) => (x.weight_kg != null && Number.isFinite(x.weight_kg) ? `${Number(x.weight_kg.toFixed(1))}` : "\u2013")],
    fields: ["name", "weight_kg"],
    deletePermission: "horse.delete", // the same permission covers riders
  },
  saddles: {
    url: "/api/saddles",
    noun: "saddle",
    columns: [(x) => h("a", { href: `#/saddles/${x.id}` }, x.name), (x) => x.maker ?? "", (x) => saddleTypeText(x.saddle_type),
              (x) => x.tree_width ?? "", (x) => String(x.rides ?? 0)],
    fields: ["name", "maker", "saddle_type", "tree_width", "notes"],
    deletePermission: "saddle.delete",
  },
};

/** @param {string} word */
function capitalised(word) {
  return word[0].toUpperCase() + word.slice(1);
}

/**
 * The page of one kind of list (app.js: "horses", "riders" or "saddles").
 * @param {keyof KINDS} kindName
 * @returns {import("../router.js").Mount}
 */
export function mountEntities(kindName) {
  return async (view, params, query) => {
    // each kind's columns read the rows its own url answers: one kind's rows never meet another's columns
    const kind = /** @type {Kind<Entity>} */ (/** @type {unknown} */ (KINDS[kindName]));
    view.append(page(kindName));
    const state = listState(query ?? new URLSearchParams(), { filters: ["q"], sort: "name" });
    const pagerSlot = one(view, "[data-entity-pager]");
    const tableWrap = one(view, ".table-wrap");
    // Errors of the list (a refused deletion) show above it, not in the add form.
    const listPanel = /** @type {HTMLElement} */ (tableWrap.closest(".panel"));
    one(listPanel, "h2").after(h("p", { class: "form-error", role: "alert", "data-form-error": true, hidden: true }));
    const table = one(view, "[data-entity-table]", HTMLTableElement);
    const empty = one(view, "[data-entity-empty]");
    const form = one(view, "[data-entity-form]", HTMLFormElement);
    const title = one(view, "[data-entity-form-title]");
    const submit = one(view, "[data-entity-submit]");
    const cancel = one(view, "[data-entity-cancel]");
    /** @type {Entity | null} */
    let editing = null;

    /** @param {Entity | null} item */
    function setEditing(item) {
      editing = item;
      form.reset();
      showError(form, null);
      if (item) {
        for (const name of kind.fields) {
          const el = maybeControl(form, name);
          const value = /** @type {Record<string, unknown>} */ (/** @type {unknown} */ (item))[name]; // a field of the row
          if (el && value !== null && value !== undefined) el.value = String(value);
        }
      }
      title.textContent = item ? `Edit ${item.name}` : `Add a ${kind.noun}`;
      submit.textContent = item ? "Save changes" : `Add ${kind.noun}`;
      cancel.hidden = !item;
      if (item) control(form, "name").focus();
    }

    /** @param {Entity} item */
    function actions(item) {
      const cell = h("td", { class: "actions" },
        h("button", { type: "button", class: "link-button", "aria-label": `Edit ${item.name}`,
                      onclick: () => setEditing(item) }, "Edit"));
      if (can(kind.deletePermission)) { // admins only
        cell.append(h("button", { type: "button", class: "link-button danger", "data-permission": kind.deletePermission,
                                  "aria-label": `Delete ${item.name}`, onclick: () => remove(item) }, "Delete"));
      }
      return cell;
    }

    async function load() {
      /** @type {{items: Entity[], total: number, limit: number, offset: number}} a Page of the kind's rows */
      const answer = await get(kind.url, { params: apiParams(state) });
      const items = itemsOf(answer);
      table.tBodies[0].replaceChildren(...items.map((item) => h("tr", { dataset: { id: item.id } },
        ...kind.columns.map((col, i) => (i === 0 ? h("th", { scope: "row" }, col(item)) : h("td", {}, col(item)))),
        actions(item))));
      tableWrap.hidden = !items.length;
      empty.hidden = items.length > 0;
      pagerSlot.replaceChildren(pager(answer, state, { noun: kindName }));
    }

    /** @param {Entity} item */
    async function remove(item) {
      if (!window.confirm(`Delete ${kind.noun} ${item.name}?`)) return;
      showError(listPanel, null);
      try {
        await del(`${kind.url}/${item.id}`);
        announce(`${capitalised(kind.noun)} ${item.name} deleted.`);
        if (editing?.id === item.id) setEditing(null);
        await load();
      } catch (error) {
        showError(listPanel, error); // e.g. 409: rides still use it, saying how many
      }
    }

    form.addEventListener("submit", async (event) => {
      event.preventDefault();
      if (!control(form, "name").value.trim()) {
        showError(form, "Please fill in the name.");
        control(form, "name").focus();
        return;
      }
      /** @type {Record<string, string | number | null>} */
      const values = formValues(form);
      if (editing) {
        // Cleared optional fields are sent as null so the server forgets them.
        for (const name of kind.fields) if (!(name in values)) values[name] = null;
      }
      try {
        const target = editing;
        /** @type {Entity | null} */
        const saved = await busy(form, () => (target ? patch(`${kind.url}/${target.id}`, values) : post(kind.url, values)));
        announce(`${capitalised(kind.noun)} ${saved?.name ?? values.name} ${editing ? "saved" : "added"}.`);
        setEditing(null);
        await load();
      } catch (error) {
        showError(form, error);
      }
    });
    cancel.addEventListener("click", () => setEditing(null));
    await fillOptions(form).catch((error) => showError(form, error)); // the saddle types
    bindFilterForm(one(view, "[data-entity-filter]", HTMLFormElement), state);

    try {
      await load();
    } catch (error) {
      showError(listPanel, error);
    }
  };
}
