// A refused form's reason in plain sentences: the API's validation errors ("body.password: String should
// have at least 8 characters") said per field in the form's own words ("The password needs at least 8
// characters."), and its other reasons as a sentence (capital letter, full stop).

/** @typedef {Partial<import("./api-types").ValidationError>} FieldError one item of a 422's `detail` */

/** @type {Record<string, string>} */
const FIELD_WORDS = {
  password: "the password", new_password: "the new password", email: "the e-mail address",
  club_name: "the club's name", display_name: "your name", username: "the e-mail address",
  wand_length_m: "the wand's length",
};
// Fields whose validator's message is already a sentence for the club (it says the range and the likely slip).
const OWN_SENTENCE = new Set(["wand_length_m"]);

/** @param {FieldError} item */
function fieldName(item) {
  return Array.isArray(item.loc) ? String(item.loc[item.loc.length - 1]) : "";
}

/** @param {FieldError} item */
function fieldWords(item) {
  const name = fieldName(item);
  return FIELD_WORDS[name] ?? (name ? `the ${name.replaceAll("_", " ")}` : "a field");
}

/** @param {unknown} text */
function capital(text) {
  const t = String(text).trim();
  if (!t) return t;
  return t[0].toUpperCase() + t.slice(1) + (/[.!?]$/.test(t) ? "" : ".");
}

/**
 * One validation error of the API as a sentence about its field.
 * @param {FieldError} item
 * @returns {string}
 */
function fieldSentence(item) {
  const field = fieldWords(item);
  // pydantic's limits (its ctx) are not always sent: read them from its message then ("at least 8 characters")
  const number = (String(item.msg ?? "").match(/(\d+)/) || [])[1];
  /** @type {Record<string, unknown>} */
  const ctx = { min_length: number, max_length: number, ...(item.ctx || {}) };
  switch (item.type) {
    case "string_too_short":
      return capital(ctx.min_length === 1 ? `please fill in ${field}` : `${field} needs at least ${ctx.min_length} characters`);
    case "string_too_long":
      return capital(`${field} can have at most ${ctx.max_length} characters`);
    case "missing":
      return capital(`please fill in ${field}`);
    case "value_error":
      if (OWN_SENTENCE.has(fieldName(item))) return capital(String(item.msg ?? "").replace(/^Value error, /, ""));
      return capital(field === "the e-mail address" ? "please give a valid e-mail address, like name@club.org"
        : `${field} is not valid`);
    default:
      return capital(`${field} is not valid`);
  }
}

/**
 * The error of a refused form as plain sentences (a network failure or a string as it is, made a sentence).
 * @param {unknown} error an ApiError (its body's `errors`: the 422's items), an Error or a sentence
 * @returns {string}
 */
export function plainReason(error) {
  if (typeof error === "string") return capital(error);
  const refused = /** @type {{body?: {errors?: unknown}, message?: string} | null | undefined} */ (error);
  const items = refused?.body?.errors;
  if (Array.isArray(items) && items.length) return [...new Set(items.map(fieldSentence))].join(" ");
  return capital(refused?.message ?? "Something went wrong; please try again.");
}
