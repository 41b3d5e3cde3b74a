// Headless-Chromium test of the demo page of `tre serve` (run by tests/demo_page.rs).
//
//   node tests/browser/demo.mjs http://127.0.0.1:PORT path/to/image.png path/to/depth.png \
//        path/to/camera.json
//
// Drives Debian's Chromium (CHROMIUM, default /usr/bin/chromium) with playwright-core: picks the
// image, waits for the roughness overlay and checks that it really rendered (size, colours,
// legend, stage timings, the answer's mode, gravity and assumptions), streams it over the
// WebSocket until 3 results came back, sends the depth PNG through the three-state section
// (first with the sensor alone: no camera part, intrinsics and depth scale assumed; then with
// the camera JSON, which fills the Camera fields and goes as the `camera` part: nothing
// assumed; unknown in its own colour, legend) and then with the picked image (RGB + depth: the
// rgb part goes along and the answer names rgbd), then submits a text file and checks that the
// server's error message is shown. Exits 0 when every check passes, 1 with the failed check
// otherwise. TRE_SCREENSHOT=path saves a screenshot of the page.
import { mkdtempSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { chromium } from "playwright-core";

const RESULT_TIMEOUT_MS = 180_000;
const CHROMIUM_ARGS = [
  "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
  "--disable-background-networking", "--disable-component-update", "--disable-sync",
];

class CheckFailed extends Error {}

function check(cond, what) {
  if (!cond) throw new CheckFailed(what);
  console.log(`ok: ${what}`);
}

/** Width and height from a PNG's IHDR, or null for another format. */
function pngSize(bytes) {
  const sig = [0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a];
  if (bytes.length < 24 || !sig.every((b, i) => bytes[i] === b)) return null;
  return { width: bytes.readUInt32BE(16), height: bytes.readUInt32BE(20) };
}

/** Pixel statistics of an <img> or <canvas> drawn on a canvas in the page. */
function pixelStats(page, selector) {
  return page.evaluate((sel) => {
    const el = document.querySelector(sel);
    const w = el.naturalWidth ?? el.width, h = el.naturalHeight ?? el.height;
    if (!w || !h) return { width: 0, height: 0, colours: 0, nonBlack: 0, opaque: 0, total: 0 };
    const c = document.createElement("canvas");
    c.width = w;
    c.height = h;
    const g = c.getContext("2d");
    g.drawImage(el, 0, 0);
    const d = g.getImageData(0, 0, w, h).data;
    const colours = new Set();
    let nonBlack = 0, opaque = 0;
    for (let i = 0; i < d.length; i += 4) {
      if (d[i + 3] === 0) continue;
      opaque += 1;
      if (d[i] + d[i + 1] + d[i + 2] > 30) nonBlack += 1;
      colours.add(((d[i] >> 3) << 10) | ((d[i + 1] >> 3) << 5) | (d[i + 2] >> 3));
    }
    return { width: w, height: h, colours: colours.size, nonBlack, opaque, total: w * h };
  }, selector);
}

async function waitForResult(page, what) {
  await page.waitForFunction(
    () => ["done", "error"].includes(document.body.dataset.state), null,
    { timeout: RESULT_TIMEOUT_MS },
  );
  const state = await page.evaluate(() => document.body.dataset.state);
  const error = (await page.textContent("#error")).trim();
  check(state === "done", `${what} rendered (state ${state}${error ? `, #error: ${error}` : ""})`);
}

async function checkSingleImage(page, imagePath) {
  const bytes = readFileSync(imagePath);
  await page.setInputFiles("#file", imagePath);
  await waitForResult(page, "the roughness of the picked image");
  const input = pngSize(bytes) ?? await page.evaluate(() => {
    const img = document.getElementById("input-img");
    return { width: img.naturalWidth, height: img.naturalHeight };
  });
  const overlay = await pixelStats(page, "#overlay");
  console.log(`overlay: ${JSON.stringify(overlay)}`);
  check(overlay.width === input.width && overlay.height === input.height,
    `overlay is ${overlay.width}×${overlay.height}, as the input (${input.width}×${input.height})`);
  check(overlay.colours > 1, `overlay has more than one colour (${overlay.colours})`);
  check(overlay.nonBlack > 0, `overlay has non-black pixels (${overlay.nonBlack})`);
  check(await page.isVisible("#overlay"), "overlay is visible");
  const legend = await pixelStats(page, "#legend");
  check(legend.opaque > 0 && legend.colours > 10,
    `legend is drawn (${legend.opaque} px, ${legend.colours} colours)`);
  const timings = await page.textContent("#timings");
  console.log(`timings: ${timings.replace(/\s+/g, " ").trim()}`);
  check(/depth/.test(timings) && /normals/.test(timings), "#timings names depth and normals");
  const workingSize = (await page.textContent("#working-size")).trim();
  check(/\d+\s*×\s*\d+/.test(workingSize), `working size shown (${workingSize})`);
  check((await page.textContent("#error")).trim() === "", "no error shown");
  // No camera given: the answer names its mode and gravity, and the intrinsics as assumed.
  const answer = await answerShown(page, "#image-answer");
  check(answer.mode === "rgb", `image answer names the mode that ran (${answer.mode})`);
  check(answer.assumed.includes("intrinsics"),
    `image answer shows the assumed intrinsics (${answer.assumed})`);
  const caveat = await page.$eval("#image-answer", (el) => {
    const c = el.querySelector(".caveat");
    return c ? { text: c.textContent, warn: c.classList.contains("warn") } : null;
  });
  check(caveat !== null && /predicted depth/.test(caveat.text) && /unknown/.test(caveat.text)
    && caveat.warn, `an rgb answer carries its caveat (${caveat && caveat.text})`);
}

/** The answer line in `selector`: mode, gravity source, assumed keys, texts, whether visible and
 *  whether the assumptions are styled apart (as warnings). */
async function answerShown(page, selector) {
  const a = await page.$eval(selector, (el) => {
    const warnings = [...el.querySelectorAll("li")];
    const assumed = el.querySelector(".assumed");
    const plain = getComputedStyle(el).color;
    return {
      mode: el.dataset.mode || "", gravity: el.dataset.gravity || "",
      assumed: (el.dataset.assumed || "").split(",").filter(Boolean),
      text: el.textContent.replace(/\s+/g, " ").trim(),
      warnings: warnings.map((li) => li.textContent),
      warningStyled: warnings.every((li) => getComputedStyle(li).color !== plain)
        && (!assumed || !assumed.classList.contains("warn")
            || getComputedStyle(assumed).color !== plain),
    };
  });
  a.visible = await page.isVisible(selector);
  console.log(`${selector}: ${a.text}`);
  check(a.visible && a.mode !== "", `${selector} shown with the mode that ran`);
  check(/^(stated|estimated|unknown)$/.test(a.gravity), `${selector} shows gravity (${a.gravity})`);
  check(a.warnings.length === a.assumed.length,
    `${selector}: one warning in words per assumption (${a.warnings.length}, ${a.assumed.length})`);
  check(a.warningStyled, `${selector}: assumptions styled as warnings`);
  return a;
}

/** Waits until the depth section has an answer or an error, for a change made by `act`. */
async function depthRun(page, act) {
  await page.evaluate(() => { document.getElementById("sensor").dataset.state = "waiting"; });
  await act();
  await page.waitForFunction(
    () => ["done", "error"].includes(document.getElementById("sensor").dataset.state), null,
    { timeout: RESULT_TIMEOUT_MS },
  );
  return page.evaluate(() => document.getElementById("sensor").dataset.state);
}

/** The Camera fields: labelled inputs for every parameter, a sensor choice, a camera file. */
async function checkCameraFields(page) {
  const fields = await page.$$eval("#camera [name]", (els) => els.map((el) => ({
    name: el.name, labelled: Boolean(el.id && document.querySelector(`label[for="${el.id}"]`)),
  })));
  const names = fields.map((f) => f.name);
  for (const name of ["fx", "fy", "cx", "cy", "depth_scale", "sensor", "pitch_deg", "height_m"]) {
    check(names.includes(name), `camera field ${name}`);
  }
  check(fields.every((f) => f.labelled), "every camera field has a label");
  check(await page.$("#camera-file") !== null, "camera JSON file input");
  const sensors = await page.$$eval("#cam-sensor option", (o) => o.map((x) => x.value));
  const presets = process.env.TRE_SENSOR_PRESETS;
  check(Boolean(presets), "TRE_SENSOR_PRESETS names the library's presets");
  check(sensors.join(",") === `,${presets}`,
    `sensor choices: none and the presets (${sensors})`);
}

/** The multipart parts and query of the last depth request the page sent. */
function depthRequests(page) {
  const seen = [];
  page.on("request", (r) => {
    if (r.method() === "POST" && r.url().includes("/v1/roughness?") && r.url().includes("traversal")) {
      const body = (r.postDataBuffer() || Buffer.alloc(0)).toString("latin1");
      seen.push({ url: new URL(r.url()), body });
    }
  });
  return seen;
}

/** A depth PNG through the three-state section: with no sensor the page asks for one; with the
 *  sensor alone no camera part goes and the answer names the assumed intrinsics and depth
 *  scale; an incomplete intrinsics is named inline; the camera JSON fills the fields and goes
 *  as the `camera` part, and nothing is assumed. The map is painted in the legend's colours,
 *  unknown among them, and the legend names the three states. */
async function checkTraversal(page, depthPath, cameraPath) {
  await checkCameraFields(page);
  // The depth alone first (the picked image is of another scene): geometric.
  check(await page.isChecked("#depth-with-rgb"), "RGB + depth is the default once an image is picked");
  await page.uncheck("#depth-with-rgb");
  const requests = depthRequests(page);
  let state = await depthRun(page, () => page.setInputFiles("#depth-file", depthPath));
  let error = (await page.textContent("#sensor-error")).trim();
  check(state === "error" && /noise model/.test(error) && requests.length === 0,
    `without a sensor, no request and the page asks for one (${error})`);

  state = await depthRun(page, () => page.selectOption("#cam-sensor", "kinect_v1"));
  error = (await page.textContent("#sensor-error")).trim();
  check(state === "done", `three-state map with the sensor alone${error ? ` (${error})` : ""}`);
  let sent = requests[requests.length - 1];
  check(sent && !/name="camera"/.test(sent.body) && sent.url.searchParams.get("sensor") === "kinect_v1",
    "the sensor alone goes as ?sensor=, with no camera part");
  let answer = await answerShown(page, "#depth-answer");
  check(answer.mode === "geometric", `depth answer names the mode (${answer.mode})`);
  check(answer.assumed.includes("intrinsics") && answer.assumed.includes("depth_scale"),
    `depth answer shows the assumed intrinsics and depth scale (${answer.assumed})`);

  await page.fill("#cam-fx", "500");
  const inline = (await page.textContent("#camera-error")).trim();
  check(/fx, fy, cx and cy/.test(inline) && await page.getAttribute("#cam-cy", "aria-invalid") === "true",
    `an incomplete intrinsics is named inline (${inline})`);

  const camera = JSON.parse(readFileSync(cameraPath, "utf8"));
  state = await depthRun(page, () => page.setInputFiles("#camera-file", cameraPath));
  error = (await page.textContent("#sensor-error")).trim();
  check(state === "done", `three-state map with the camera JSON${error ? ` (${error})` : ""}`);
  const filled = await page.$$eval("#camera [name]", (els) =>
    Object.fromEntries(els.map((el) => [el.name, el.value])));
  check(Number(filled.fx) === camera.fx && Number(filled.depth_scale) === camera.depth_scale
    && filled.sensor === camera.sensor && filled.pitch_deg === "" && (await page.textContent("#camera-error")) === "",
    `the camera JSON fills the fields (${JSON.stringify(filled)})`);
  sent = requests[requests.length - 1];
  const part = /name="camera"; filename="camera\.json"\r\nContent-Type: application\/json\r\n\r\n(.*?)\r\n--/s
    .exec(sent.body);
  const json = part ? JSON.parse(part[1]) : {};
  check(json.fx === camera.fx && json.depth_scale === camera.depth_scale && json.sensor === camera.sensor
    && !sent.url.searchParams.has("sensor"),
    `the camera goes as the part camera.json, application/json (${part ? part[1].slice(0, 80) : "none"}…)`);
  answer = await answerShown(page, "#depth-answer");
  check(answer.assumed.length === 0 && /Nothing assumed/.test(answer.text),
    `with the camera nothing is assumed (${answer.assumed})`);
  // The image goes again, with the camera: its intrinsics are no longer assumed.
  await page.waitForFunction(() => document.body.dataset.state !== "loading", null,
    { timeout: RESULT_TIMEOUT_MS });
  const image = await answerShown(page, "#image-answer");
  check(!image.assumed.includes("intrinsics"), `the image went with the camera (${image.assumed})`);
  const legend = await page.$$eval("#traversal-legend li", (li) => li.map((l) => l.dataset.state));
  check(legend.join(",") === "unknown,traversable,hazard", `legend names the states (${legend})`);
  const seen = await page.evaluate(() => {
    const c = document.getElementById("traversal-view");
    const d = c.getContext("2d").getImageData(0, 0, c.width, c.height).data;
    return window.tre.TRAVERSAL.map(({ rgb }) => {
      let n = 0;
      for (let i = 0; i < d.length; i += 4) {
        if (d[i] === rgb[0] && d[i + 1] === rgb[1] && d[i + 2] === rgb[2]) n += 1;
      }
      return n;
    });
  });
  console.log(`three-state pixels (unknown, traversable, hazard): ${seen}`);
  // Without the frame's mounting the slope test uses the default one (60° down), so which of
  // traversable and hazard the near floor gets depends on the frame; unknown must show.
  const size = await page.evaluate(() => {
    const c = document.getElementById("traversal-view");
    return c.width * c.height;
  });
  check(size > 0 && seen.reduce((a, b) => a + b, 0) === size,
    `every pixel in one of the three colours (${size} px)`);
  check(seen[0] > 0 && seen[1] + seen[2] > 0, "unknown shown in its own colour beside the others");
  const shares = (await page.textContent("#sensor-shares")).trim();
  check(/unknown \d/.test(shares), `shares shown (${shares})`);
}

/** RGB + depth: with the box ticked the depth goes with the picked image as its rgb part, the
 *  page asks for the mode that works on both (rgbd), shows it, and the answer names it. */
async function checkRgbWithDepth(page) {
  const requests = depthRequests(page);
  const state = await depthRun(page, () => page.check("#depth-with-rgb"));
  const error = (await page.textContent("#sensor-error")).trim();
  check(state === "done", `RGB + depth answered${error ? ` (${error})` : ""}`);
  const sent = requests[requests.length - 1];
  check(sent && /name="rgb"/.test(sent.body) && /name="depth"/.test(sent.body)
    && sent.url.searchParams.get("mode") === "rgbd",
    "the picked image goes with the depth as its rgb part, mode rgbd");
  const answer = await answerShown(page, "#depth-answer");
  check(answer.mode === "rgbd", `the RGB + depth answer names rgbd (${answer.mode})`);
  const shown = (await page.textContent("#depth-mode-name")).trim();
  check(shown === "rgbd", `the page shows the mode from its inputs (${shown})`);
}

/** Clear camera: the fields empty, no camera part; the image goes again without one. */
async function clearCamera(page) {
  await page.click("#camera-clear");
  await page.waitForFunction(() => document.body.dataset.state !== "loading", null,
    { timeout: RESULT_TIMEOUT_MS });
  const json = (await page.textContent("#camera-json")).trim();
  check(/no camera part/.test(json), `Clear camera leaves no camera part (${json})`);
}

async function checkStream(page) {
  await page.click("#stream-start");
  await page.waitForFunction(() => {
    const n = parseInt(document.getElementById("stream-count").textContent, 10);
    const err = document.getElementById("stream-error").textContent;
    return n >= 3 || err !== "" || document.getElementById("stream-state").dataset.state === "closed";
  }, null, { timeout: RESULT_TIMEOUT_MS });
  const count = parseInt(await page.textContent("#stream-count"), 10);
  const streamError = (await page.textContent("#stream-error")).trim();
  check(count >= 3, `3 stream results received (${count}${streamError ? `; ${streamError}` : ""})`);
  await page.waitForFunction(() => document.getElementById("stream-view").naturalWidth > 0, null,
    { timeout: 10_000 });
  const view = await pixelStats(page, "#stream-view");
  check(view.width > 0 && view.colours > 1 && view.nonBlack > 0,
    `stream view shows a colour map (${view.width}×${view.height}, ${view.colours} colours)`);
  const dropped = (await page.textContent("#stream-dropped")).trim();
  check(/^\d+$/.test(dropped), `dropped counter shown (${dropped})`);
  check(streamError === "", "no stream error shown");
  await page.click("#stream-start");
  await page.waitForFunction(
    () => document.getElementById("stream-state").dataset.state === "closed", null,
    { timeout: 10_000 },
  );
  check(true, "stream stopped");
}

async function checkBadInput(page, baseUrl) {
  const dir = mkdtempSync(join(tmpdir(), "tre-demo-"));
  const path = join(dir, "not-an-image.txt");
  const text = "this is not an image\n";
  writeFileSync(path, text);
  try {
    // The same request straight to the server, for the message the page must show.
    const resp = await fetch(`${baseUrl}/v1/roughness?format=color&preview_max_cm=5`, {
      method: "POST", body: text, headers: { "Content-Type": "text/plain" },
    });
    const body = await resp.text();
    check(resp.status >= 400 && resp.status < 500, `server refuses a text file (HTTP ${resp.status})`);
    const message = JSON.parse(body).error.message;
    await page.setInputFiles("#file", path);
    await page.waitForFunction(() => document.body.dataset.state !== "loading", null,
      { timeout: RESULT_TIMEOUT_MS });
    const shown = (await page.textContent("#error")).trim();
    console.log(`#error: ${shown}`);
    check(shown.includes(message), `#error shows the server's message "${message}"`);
    check(await page.evaluate(() => document.body.dataset.state) === "error", "page state is error");
  } finally {
    rmSync(dir, { recursive: true, force: true });
  }
}

async function main() {
  const [baseArg, imagePath, depthPath, cameraPath] = process.argv.slice(2);
  if (!baseArg || !imagePath || !depthPath || !cameraPath) {
    console.error("usage: node demo.mjs BASE_URL IMAGE DEPTH_PNG CAMERA_JSON");
    return 2;
  }
  const baseUrl = baseArg.replace(/\/+$/, "");
  const userDataDir = mkdtempSync(join(tmpdir(), "tre-chromium-"));
  const context = await chromium.launchPersistentContext(userDataDir, {
    executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
    headless: true,
    args: CHROMIUM_ARGS,
    viewport: { width: 1280, height: 1100 },
  });
  const pageErrors = [];
  const page = context.pages()[0] ?? await context.newPage();
  page.on("pageerror", (e) => pageErrors.push(e.message));
  page.on("console", (m) => { if (m.type() === "error") console.log(`console error: ${m.text()}`); });
  const screenshot = async () => {
    if (process.env.TRE_SCREENSHOT) {
      await page.screenshot({ path: process.env.TRE_SCREENSHOT, fullPage: true }).catch(() => {});
      console.log(`screenshot: ${process.env.TRE_SCREENSHOT}`);
    }
  };
  try {
    const resp = await page.goto(`${baseUrl}/`);
    check(resp && resp.ok(), `GET / answers ${resp && resp.status()}`);
    check(await page.title() === "tre — terrain roughness", "page title");
    await checkSingleImage(page, imagePath);
    await checkStream(page);
    await checkTraversal(page, depthPath, cameraPath);
    await checkRgbWithDepth(page);
    await screenshot();
    await clearCamera(page);
    await checkBadInput(page, baseUrl);
    check(pageErrors.length === 0, `no uncaught errors in the page (${pageErrors.join("; ")})`);
    console.log("demo page: all checks passed");
    return 0;
  } catch (e) {
    await screenshot();
    const what = e instanceof CheckFailed ? "check failed" : "error";
    console.error(`demo page test FAILED (${what}): ${e.message}`);
    if (pageErrors.length) console.error(`uncaught errors in the page: ${pageErrors.join("; ")}`);
    return 1;
  } finally {
    await context.close().catch(() => {});
    rmSync(userDataDir, { recursive: true, force: true });
  }
}

process.exitCode = await main().catch((e) => {
  console.error(`demo page test FAILED: ${e.stack || e}`);
  return 1;
});
