// The console's one DOM helper, in a W3C DOM (jsdom: Debian's node-jsdom, which `make node`
// installs; NODE_PATH=/usr/share/nodejs finds it, as the Makefile sets).
import assert from "node:assert/strict";
import { createRequire } from "node:module";
import { test } from "node:test";

const { JSDOM } = createRequire(import.meta.url)("jsdom");
const { window } = new JSDOM('<!doctype html><body><p id="here">x</p></body>');
globalThis.document = window.document;

const { $, el } = await import("../../web/lib/dom.js");

test("$ finds an element by its id, and null for none", () => {
  assert.equal($("here").textContent, "x");
  assert.equal($("nowhere"), null);
});

test("el makes the tag with its properties assigned", () => {
  const button = el("button", { type: "button", className: "a b", textContent: "Go", title: "why" });
  assert.equal(button.tagName, "BUTTON");
  assert.equal(button.outerHTML, '<button type="button" class="a b" title="why">Go</button>');
  assert.equal(el("td").outerHTML, "<td></td>");
});

test("el adds dataset entries as data- attributes, not as a property", () => {
  const row = el("tr", { dataset: { testid: "alarm-row", alarmId: "7" } });
  assert.equal(row.getAttribute("data-testid"), "alarm-row");
  assert.equal(row.getAttribute("data-alarm-id"), "7");
  assert.equal(row.dataset.alarmId, "7");
});

test("el appends children in order, text as text (never as markup), skipping null and undefined", () => {
  const item = el("li", {}, "a <b>", null, el("span", { textContent: "c" }), undefined, "d");
  assert.equal(item.childNodes.length, 3);
  assert.equal(item.innerHTML, "a &lt;b&gt;<span>c</span>d");
  assert.equal(item.querySelector("b"), null);
});

test("textContent from the props is text too", () => {
  assert.equal(el("p", { textContent: "<i>no</i>" }).querySelector("i"), null);
});
