// The console's one DOM helper.

/** The element with this id. */
export const $ = (id) => document.getElementById(id);

/**
 * A new element: `props` are assigned to it (className, textContent, title, type, ...),
 * except `dataset`, whose entries are added to its data- attributes; `children` (nodes or
 * strings; null and undefined skipped) are appended.
 * @param {string} tag
 * @param {Record<string, any>} [props]
 * @param {...(Node|string|null|undefined)} children
 * @returns {HTMLElement}
 */
export function el(tag, props = {}, ...children) {
  const { dataset, ...rest } = props;
  const node = Object.assign(document.createElement(tag), rest);
  if (dataset) Object.assign(node.dataset, dataset);
  node.append(...children.filter((c) => c !== null && c !== undefined));
  return node;
}
