// The console's API client (web/lib/api.js) against a real HTTP server on a free port:
// every call carries the held token, and every answer comes back as {ok, status, body}.
import assert from "node:assert/strict";
import { createServer } from "node:http";
import { after, before, beforeEach, test } from "node:test";

import { api, detailText, getJson, heldToken, holdToken, onTokenRefused } from "../../web/lib/api.js";

const seen = []; // [method, url, authorization, content-type] of each request
let base = "";
const server = createServer((req, res) => {
  seen.push([req.method, req.url, req.headers.authorization, req.headers["content-type"]]);
  const answer = (status, body, type = "application/json") => {
    res.writeHead(status, { "Content-Type": type });
    res.end(type === "application/json" ? JSON.stringify(body) : body);
  };
  if (req.url === "/ok") answer(200, { fine: true });
  else if (req.url === "/refused") answer(403, { detail: "wrong token: revoked" });
  else if (req.url === "/role") answer(403, { detail: "this needs the operator role" });
  else if (req.url === "/invalid") answer(422, { detail: [{ loc: ["body", "x"], msg: "x: must be in [0, 1]" }, { msg: "y: required" }] });
  else if (req.url === "/html") answer(502, "<html>bad gateway</html>", "text/html");
  else answer(404, { detail: "Not Found" });
});

before(async () => {
  await new Promise((resolve) => server.listen(0, "127.0.0.1", resolve));
  base = `http://127.0.0.1:${server.address().port}`;
});
after(() => server.close());
beforeEach(() => { seen.length = 0; holdToken(""); onTokenRefused(null); });

test("every call carries the held token: GET, a JSON POST, a form upload", async () => {
  holdToken("tab-token-1");
  await api(`${base}/ok`);
  await api(`${base}/ok`, { method: "POST", headers: { "Content-Type": "application/json" }, body: "{}" });
  const form = new FormData();
  form.append("file", new Blob(["SEQUENCE s\n"]), "s.seq");
  await api(`${base}/ok`, { method: "POST", body: form });
  assert.deepEqual(seen.map((r) => r[2]), ["Bearer tab-token-1", "Bearer tab-token-1", "Bearer tab-token-1"]);
  assert.equal(seen[1][3], "application/json");
  assert.match(seen[2][3], /^multipart\/form-data; boundary=/);
});

test("no token held: no Authorization header; a candidate token is sent in its place", async () => {
  await api(`${base}/ok`);
  holdToken("held");
  await api(`${base}/ok`, { token: "candidate" });
  await api(`${base}/ok`, { token: "" });
  assert.deepEqual(seen.map((r) => r[2]), [undefined, "Bearer candidate", undefined]);
});

test("answers come back as {ok, status, body}", async () => {
  assert.deepEqual(await api(`${base}/ok`), { ok: true, status: 200, body: { fine: true } });
  const html = await api(`${base}/html`);
  assert.deepEqual(html, { ok: false, status: 502, body: null });
  assert.equal(detailText(html), "HTTP 502");
  const invalid = await api(`${base}/invalid`);
  assert.equal(invalid.status, 422);
  assert.equal(detailText(invalid), "x: must be in [0, 1]; y: required");
  assert.equal(detailText(await api(`${base}/role`)), "this needs the operator role");
});

test("a request that cannot be sent answers status 0 with the reason", async () => {
  const closed = createServer();
  await new Promise((resolve) => closed.listen(0, "127.0.0.1", resolve));
  const port = closed.address().port;
  await new Promise((resolve) => closed.close(resolve));
  const r = await api(`http://127.0.0.1:${port}/ok`);
  assert.equal(r.ok, false);
  assert.equal(r.status, 0);
  assert.match(detailText(r), /^not sent: /);
});

test("a held token the API refuses is forgotten, and the tab is told once", async () => {
  const told = [];
  onTokenRefused((detail) => { told.push([detail, heldToken()]); });
  holdToken("revoked-token");
  const r = await api(`${base}/refused`);
  assert.equal(r.status, 403);
  assert.deepEqual(told, [["wrong token: revoked", ""]]);
  await api(`${base}/refused`, { token: "a-candidate" }); // a sign-in's check: not the held one
  await api(`${base}/role`);
  assert.equal(told.length, 1);
});

test("getJson gives the body, or throws the API's sentence", async () => {
  assert.deepEqual(await getJson(`${base}/ok`), { fine: true });
  await assert.rejects(getJson(`${base}/missing`), { message: "Not Found" });
  await assert.rejects(getJson(`${base}/invalid`), { message: "x: must be in [0, 1]; y: required" });
});
