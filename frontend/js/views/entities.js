// Horses, riders and saddles: a list searched, sorted and paged by the server (state in the URL:
// #/horses?q=bra&page=2), with edit buttons, next to a form that adds or edits one. Delete is for
// admins only (horse.delete, saddle.delete), so nobody else sees it. A horse's name opens its page
// (#/horses/:id), a saddle's its page across horses (#/saddles/:id).

import { del, get, itemsOf, patch, post } from "../api.js";
import { announce, busy, formValues, h, page, showError } from "../dom.js";
import { fmt } from "../format.js";
import { fillOptions } from "../options.js";
import { apiParams, bindFilterForm, listState, pager } from "../pager.js";
import { saddleTypeText } from "../saddle-words.js";
import { can } from "../session.js";

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
    columns: [(x) => x.name, (x) => (Number.isFinite(x.weight_kg) ? `${Number(x.weight_kg.toFixed(1))}` : "\u2013")],
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

function capitalised(word) {
  return word[0].toUpperCase() + word.slice(1);
}

export function mountEntities(kindName) {
  return async (view, params, query) => {
    const kind = KINDS[kindName];
    view.append(page(kindName));
    const state = listState(query ?? new URLSearchParams(), { filters: ["q"], sort: "name" });
    const pagerSlot = view.querySelector("[data-entity-pager]");
    const tableWrap = view.querySelector(".table-wrap");
    // Errors of the list (a refused deletion) show above it, not in the add form.
    const listPanel = tableWrap.closest(".panel");
    listPanel.querySelector("h2").after(h("p", { class: "form-error", role: "alert", "data-form-error": true, hidden: true }));
    const table = view.querySelector("[data-entity-table]");
    const empty = view.querySelector("[data-entity-empty]");
    const form = view.querySelector("[data-entity-form]");
    const title = view.querySelector("[data-entity-form-title]");
    const submit = view.querySelector("[data-entity-submit]");
    const cancel = view.querySelector("[data-entity-cancel]");
    let editing = null;

    function setEditing(item) {
      editing = item;
      form.reset();
      showError(form, null);
      if (item) {
        for (const name of kind.fields) {
          if (form.elements[name] && item[name] !== null && item[name] !== undefined) form.elements[name].value = item[name];
        }
      }
      title.textContent = item ? `Edit ${item.name}` : `Add a ${kind.noun}`;
      submit.textContent = item ? "Save changes" : `Add ${kind.noun}`;
      cancel.hidden = !item;
      if (item) form.elements.name.focus();
    }

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
      const answer = await get(kind.url, { params: apiParams(state) });
      const items = itemsOf(answer);
      table.tBodies[0].replaceChildren(...items.map((item) => h("tr", { dataset: { id: item.id } },
        ...kind.columns.map((col, i) => (i === 0 ? h("th", { scope: "row" }, col(item)) : h("td", {}, col(item)))),
        actions(item))));
      tableWrap.hidden = !items.length;
      empty.hidden = items.length > 0;
      pagerSlot.replaceChildren(pager(answer, state, { noun: kindName }));
    }

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
      if (!form.elements.name.value.trim()) {
        showError(form, "Please fill in the name.");
        form.elements.name.focus();
        return;
      }
      const values = formValues(form);
      if (editing) {
        // Cleared optional fields are sent as null so the server forgets them.
        for (const name of kind.fields) if (!(name in values)) values[name] = null;
      }
      try {
        const saved = await busy(form, () => (editing ? patch(`${kind.url}/${editing.id}`, values) : post(kind.url, values)));
        announce(`${capitalised(kind.noun)} ${saved?.name ?? values.name} ${editing ? "saved" : "added"}.`);
        setEditing(null);
        await load();
      } catch (error) {
        showError(form, error);
      }
    });
    cancel.addEventListener("click", () => setEditing(null));
    await fillOptions(form).catch((error) => showError(form, error)); // the saddle types
    bindFilterForm(view.querySelector("[data-entity-filter]"), state);

    try {
      await load();
    } catch (error) {
      showError(listPanel, error);
    }
  };
}
