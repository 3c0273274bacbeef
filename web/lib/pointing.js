// A drive line with the VO pointing the advisor recommends (server.terrain.advice_api). Pure
// functions (tests/js/pointing.test.mjs).

const POINTING_ARG = /\s+vo_(?:az|el)_deg=\S*/g;

/** The 1-based line of `text` that the character offset `offset` is on. */
export function lineAt(text, offset) {
  return text.slice(0, Math.max(0, offset)).split(/\r\n|\r|\n/).length;
}

/** `line` with `args` ("vo_az_deg=90 vo_el_deg=-35") in place of any pointing it had, before
 * its comment if it has one. */
export function withPointing(line, args) {
  const hash = line.indexOf("#");
  const code = hash < 0 ? line : line.slice(0, hash);
  const comment = hash < 0 ? "" : line.slice(hash);
  const bare = code.replace(POINTING_ARG, "").replace(/\s+$/, "");
  return comment ? `${bare} ${args}    ${comment}` : `${bare} ${args}`;
}

/** `text` with its 1-based line `number` given the pointing `args` (line ends kept). */
export function textWithPointing(text, number, args) {
  const parts = text.split(/(\r\n|\r|\n)/);
  const index = 2 * (number - 1);
  if (index < 0 || index >= parts.length) return text;
  parts[index] = withPointing(parts[index], args);
  return parts.join("");
}
