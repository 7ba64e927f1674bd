// The viewer in a real browser: Debian's chromium (headless, driven by playwright-core) opens `uplvsm serve`'s page,
// picks a scene, checks camera.js's interpolation against uplvsm render's, drags the camera and checks that a new,
// different frame arrived; moves the slider, plays a preset
// (with a camera mapper), records a path and downloads it as camera-path JSON (which `uplvsm render --trajectory`
// must accept) and MP4, uploads two photos (one a portrait phone photo stored sideways with EXIF orientation 6, which
// must arrive upright), saves screenshots, then stops the server with SIGINT (clean exit).
//
// node viewer_browser_test.mjs --cli build/uplvsm --source . --work DIR [--checkpoint CK --data DS]
//   [--screenshot out.png] [--chromium /usr/bin/chromium]
// Without --checkpoint it trains a small model first (tiny config, a few steps, then the camera-mapper stage).
import { spawn, spawnSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { chromium } from 'playwright-core';

const args = Object.fromEntries(process.argv.slice(2).reduce((acc, a, i, all) => {
  if (a.startsWith('--')) acc.push([a.slice(2), all[i + 1]]);
  return acc;
}, []));
const cli = path.resolve(args.cli || 'build/uplvsm');
const source = path.resolve(args.source || '.');
const work = path.resolve(args.work || fs.mkdtempSync(path.join(os.tmpdir(), 'uplvsm_browser_')));
const chromiumPath = args.chromium || '/usr/bin/chromium';
const screenshot = args.screenshot || path.join(work, 'viewer.png');
fs.mkdirSync(work, { recursive: true });

let failures = 0;
const check = (ok, what) => {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}`);
  if (!ok) failures++;
  return ok;
};
const run = (argv) => {
  console.log('$ uplvsm ' + argv.join(' '));
  const r = spawnSync(cli, argv, { encoding: 'utf8', stdio: ['ignore', 'pipe', 'pipe'] });
  if (r.status !== 0) throw new Error(`uplvsm ${argv[0]} failed (${r.status}):\n${r.stdout}\n${r.stderr}`);
  return r.stdout;
};
for (const [what, p] of [['uplvsm binary', cli], ['chromium', chromiumPath]])
  if (!fs.existsSync(p)) { console.error(`missing ${what}: ${p} (make test installs chromium and builds uplvsm)`); process.exit(2); }

// ---- a model and a dataset ---------------------------------------------------------------------------------
let checkpoint = args.checkpoint, data = args.data;
if (!checkpoint) {
  data = path.join(work, 'dataset');
  const cfg = (name) => path.join(source, 'configs', name);
  if (!fs.existsSync(path.join(data, 'evaluation_index.json')))
    run(['make-dataset', '--config', cfg('tiny.json'), '--out', data, '--train-scenes', '24', '--test-scenes', '4']);
  run(['train', '--config', cfg('tiny.json'), '--data', data, '--run', path.join(work, 'run'), '--steps', '20',
    '--resume', 'none']);
  run(['train', '--stage', 'mapper', '--config', cfg('tiny_mapper.json'), '--init', path.join(work, 'run'),
    '--data', data, '--run', path.join(work, 'mapper'), '--steps', '5', '--resume', 'none']);
  checkpoint = path.join(work, 'mapper');
}

// ---- the server ----------------------------------------------------------------------------------------------
const server = spawn(cli, ['serve', '--checkpoint', checkpoint, ...(data ? ['--data', data] : []), '--port', '0'],
  { stdio: ['ignore', 'pipe', 'pipe'] });
let serverOut = '';
server.stdout.on('data', (d) => { serverOut += d; });
server.stderr.on('data', (d) => { serverOut += d; });
const serverExit = new Promise((resolve) => server.on('exit', (code, signal) => resolve({ code, signal })));
const url = await new Promise((resolve, reject) => {
  const timer = setTimeout(() => reject(new Error('serve printed no URL in 120 s:\n' + serverOut)), 120000);
  const poll = setInterval(() => {
    const m = serverOut.match(/open (http:\/\/127\.0\.0\.1:\d+\/)/);
    if (m) { clearInterval(poll); clearTimeout(timer); resolve(m[1]); }
  }, 100);
  server.on('exit', () => { clearInterval(poll); clearTimeout(timer); reject(new Error('serve exited:\n' + serverOut)); });
});
console.log('server at ' + url);

// ---- the browser ---------------------------------------------------------------------------------------------
const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'uplvsm_chromium_'));
const context = await chromium.launchPersistentContext(profile, {
  executablePath: chromiumPath,
  headless: true,
  acceptDownloads: true,
  viewport: { width: 1360, height: 900 },
  args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
    '--disable-background-networking', '--disable-component-update', '--disable-sync'],
});
const page = context.pages()[0] || await context.newPage();
const errors = [], foreign = [];
page.on('pageerror', (e) => errors.push(String(e)));
page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
page.on('request', (r) => { if (!/^(blob:|data:)/.test(r.url()) && !r.url().startsWith(url)) foreign.push(r.url()); });

const framesShown = () => page.$eval('#frame', (c) => Number(c.dataset.frames || 0));
// Waits until `more` frames beyond `before` (counted before the action) are on screen.
const waitFrames = async (before, more, what) => {
  await page.waitForFunction((n) => Number(document.querySelector('#frame').dataset.frames || 0) >= n,
    before + more, { timeout: 60000 }).catch(() => {});
  return check((await framesShown()) >= before + more, what);
};
// The canvas's pixels at 96x96, to compare frames (small enough to pass through the DevTools protocol quickly).
const pixels = () => page.$eval('#frame', (c) => {
  const small = document.createElement('canvas');
  small.width = small.height = 96;
  const ctx = small.getContext('2d');
  ctx.drawImage(c, 0, 0, 96, 96);
  return Array.from(ctx.getImageData(0, 0, 96, 96).data);
});
const meanDiff = (a, b) => a.reduce((s, v, i) => s + Math.abs(v - b[i]), 0) / a.length;

// An EXIF APP1 segment written by hand: a little-endian TIFF header, IFD0 with Orientation and the pointer to the EXIF
// IFD, which holds FocalLengthIn35mmFilm (as tests/io/exif_jpeg.h).
function exifApp1(orientation, focal35) {
  const b = [0x49, 0x49];
  const u16 = (v) => b.push(v & 255, (v >> 8) & 255);
  const u32 = (v) => { u16(v & 0xffff); u16(v >>> 16); };
  u16(42); u32(8);
  u16(2); u16(0x0112); u16(3); u32(1); u16(orientation); u16(0);
  u16(0x8769); u16(4); u32(1); u32(38); u32(0);
  u16(1); u16(0xa405); u16(3); u32(1); u16(focal35); u16(0); u32(0);
  const len = 2 + 6 + b.length;
  return Buffer.from([0xff, 0xe1, len >> 8, len & 255, 0x45, 0x78, 0x69, 0x66, 0, 0, ...b]);
}
// A phone's portrait photo, red over blue, 64 wide and 96 tall, stored sideways as a phone does (turned 90 degrees
// counter-clockwise: red on the left) in a JPEG the page's canvas encodes, with Orientation 6 ("turn clockwise").
async function portraitJpeg() {
  const dataUrl = await page.evaluate(() => {
    const c = document.createElement('canvas');
    c.width = 96;
    c.height = 64;
    const ctx = c.getContext('2d');
    ctx.fillStyle = '#ff0000';
    ctx.fillRect(0, 0, 48, 64);
    ctx.fillStyle = '#0000ff';
    ctx.fillRect(48, 0, 48, 64);
    return c.toDataURL('image/jpeg', 0.95);
  });
  const jpeg = Buffer.from(dataUrl.split(',')[1], 'base64');
  return Buffer.concat([jpeg.subarray(0, 2), exifApp1(6, 26), jpeg.subarray(2)]);
}
// The mean colour of the top and bottom fifths of an <img> on the page, as decoded by the browser.
const imageBands = (selector) => page.$eval(selector, async (img) => {
  await img.decode();
  const c = document.createElement('canvas');
  c.width = img.naturalWidth;
  c.height = img.naturalHeight;
  const ctx = c.getContext('2d');
  ctx.drawImage(img, 0, 0);
  const band = Math.max(1, Math.floor(c.height / 5));
  const mean = (y0) => {
    const d = ctx.getImageData(0, y0, c.width, band).data;
    const m = [0, 0, 0];
    for (let i = 0; i < d.length; i += 4) for (let k = 0; k < 3; k++) m[k] += d[i + k] / (d.length / 4);
    return m.map(Math.round);
  };
  return { top: mean(0), bottom: mean(c.height - band) };
});

try {
  await page.goto(url);
  const info = await (await page.request.get(url + 'api/info')).json();
  await page.waitForSelector('.scene-card', { timeout: 30000 });
  check((await page.$$('.scene-card')).length > 0, 'the scene list has thumbnails');
  await page.click('.scene-card');
  await page.waitForFunction(() => Number(document.querySelector('#frame').dataset.frames || 0) >= 1, null, { timeout: 60000 });
  check(true, 'picking a scene shows a first frame');
  const first = await pixels();
  // camera.js's interpolation matches `uplvsm render`'s (render/trajectory: linear translation, slerp): halfway
  // between the identity and a 90-degree turn about y at (-1.8, -0.4, 2), the camera is at half that translation
  // and has turned 45 degrees.
  const mid = await page.evaluate(() => {
    const s = Math.SQRT1_2;
    return Cam.interpolate([0, 0, 0, 0, 0, 0, 1], [-1.8, -0.4, 2, 0, s, 0, s], 0.5);
  });
  check(Math.hypot(mid[0] + 0.9, mid[1] + 0.2, mid[2] - 1) < 1e-12 &&
    Math.abs(2 * Math.acos(mid[6]) * 180 / Math.PI - 45) < 1e-9 && Math.abs(mid[3]) + Math.abs(mid[5]) < 1e-12,
  `camera.js interpolates as uplvsm render does (${mid.map((v) => v.toFixed(4)).join(', ')})`);

  const box = await page.locator('#frame').boundingBox();
  const cx = box.x + box.width / 2, cy = box.y + box.height / 2;
  const drag = async (dx, dy, steps) => {
    await page.mouse.move(cx, cy);
    await page.mouse.down();
    for (let i = 1; i <= steps; i++) await page.mouse.move(cx + dx * i, cy + dy * i);
    await page.mouse.up();
  };
  let before = await framesShown();
  await drag(14, 4, 12);
  await waitFrames(before, 1, 'dragging brings new frames');
  await page.waitForTimeout(500);  // let the last in-flight frame land
  const dragged = await pixels();
  check(meanDiff(first, dragged) > 0.5, `the dragged frame differs from the first (mean |diff| ${meanDiff(first, dragged).toFixed(2)})`);

  before = await framesShown();
  await page.$eval('#interp', (el) => { el.value = '1'; el.dispatchEvent(new Event('input')); });
  await waitFrames(before, 1, 'moving the slider renders');
  before = await framesShown();
  await page.mouse.move(cx, cy);
  await page.mouse.wheel(0, -200);
  await waitFrames(before, 1, 'the wheel dollies');
  before = await framesShown();
  await page.focus('#frame');
  await page.keyboard.press('ArrowLeft');
  await waitFrames(before, 1, 'arrow keys pan');

  // Record a drag from the reset camera, download it as JSON and MP4.
  await page.click('#reset');
  await page.click('#record');
  await drag(-8, -2, 10);
  await drag(6, 3, 14);
  await page.click('#record');
  const poses = Number((await page.textContent('#record-count')).split(' ')[0]);
  check(poses >= 2, `recording kept the dragged path (${poses} poses)`);
  const [jsonDownload] = await Promise.all([page.waitForEvent('download'), page.click('#download-json')]);
  const jsonPath = path.join(work, 'camera_path.json');
  await jsonDownload.saveAs(jsonPath);
  const doc = JSON.parse(fs.readFileSync(jsonPath, 'utf8'));
  check(doc.frames.length === poses && doc.units === (info.has_mapper ? 'baseline' : 'latent'),
    `the camera-path JSON holds the ${poses} poses in ${doc.units} units`);
  if (data) {
    run(['render', '--checkpoint', checkpoint, '--data', data, '--scenes', '1', '--trajectory', jsonPath,
      '--out', path.join(work, 'render_path')]);
    check(fs.readdirSync(path.join(work, 'render_path')).length > 0, 'uplvsm render --trajectory accepts the JSON');
  }
  const [mp4Download] = await Promise.all([page.waitForEvent('download', { timeout: 120000 }), page.click('#download-mp4')]);
  const mp4Path = path.join(work, 'path.mp4');
  await mp4Download.saveAs(mp4Path);
  const mp4 = fs.readFileSync(mp4Path);
  check(mp4.length > 1000 && mp4.subarray(4, 8).toString() === 'ftyp', `the MP4 downloads (${mp4.length} bytes)`);

  await page.waitForTimeout(500);
  await page.screenshot({ path: screenshot });
  check(fs.statSync(screenshot).size > 10000, 'screenshot saved: ' + screenshot);
  if (info.has_mapper) {
    before = await framesShown();
    await page.click('[data-preset="orbit"]');
    await waitFrames(before, 40, 'the orbit preset plays');
    await page.waitForTimeout(1000);  // the rest of the preset
  }

  // Upload two photos: a portrait phone photo stored sideways, and the second input of the open scene as a JPEG file.
  const inputs = await page.$$eval('.inputs img', (imgs) => imgs.map((i) => i.src));
  const files = [];
  for (const [i, src] of inputs.entries()) {
    const f = path.join(work, `photo${i}.jpg`);
    fs.writeFileSync(f, Buffer.from(await (await page.request.get(src)).body()));
    files.push(f);
  }
  files[0] = path.join(work, 'portrait_exif6.jpg');
  fs.writeFileSync(files[0], await portraitJpeg());
  await page.click('#tab-upload');
  await page.setInputFiles('#drop0 input', files[0]);
  await page.setInputFiles('#drop1 input', files[1]);
  const beforeUpload = await framesShown();
  await page.click('#upload-go');
  await page.waitForFunction((n) => Number(document.querySelector('#frame').dataset.frames) > n, beforeUpload, { timeout: 60000 }).catch(() => {});
  check((await framesShown()) > beforeUpload, 'two uploaded photos open as a scene');
  check(!(await page.textContent('#status')).includes('error'), 'no error shown: ' + (await page.textContent('#status')));
  const bands = await imageBands('#input0');
  check(bands.top[0] > 200 && bands.top[2] < 55 && bands.bottom[2] > 200 && bands.bottom[0] < 55,
    `the portrait photo with EXIF orientation 6 arrives upright: red at the top ${bands.top}, blue below ${bands.bottom}`);
  const notes = await page.textContent('#photo-notes');
  check(/turned upright \(EXIF orientation 6\)/.test(notes) && /from EXIF FocalLengthIn35mmFilm/.test(notes) &&
    /60\.0°, the default/.test(notes), 'the page says how each photo was turned and where its field of view came from: ' + notes);
  const uploadShot = screenshot.replace(/(\.png)?$/, '_upload.png');
  await page.screenshot({ path: uploadShot });
  check(fs.statSync(uploadShot).size > 10000, 'screenshot after the upload saved: ' + uploadShot);
  check(errors.length === 0, 'no page errors' + (errors.length ? ': ' + errors.join(' | ') : ''));
  check(foreign.length === 0, 'every request stays on the viewer\'s own origin' + (foreign.length ? ': ' + foreign.join(' ') : ''));
} catch (e) {
  check(false, 'browser session: ' + e.message);
  await page.screenshot({ path: screenshot }).catch(() => {});
} finally {
  await context.close();
  fs.rmSync(profile, { recursive: true, force: true });
}

server.kill('SIGINT');
const exit = await Promise.race([serverExit, new Promise((r) => setTimeout(() => r({ code: 'timeout' }), 30000))]);
check(exit.code === 0 && /viewer stopped/.test(serverOut), `Ctrl-C stops the server cleanly (exit ${exit.code})`);
if (exit.code === 'timeout') server.kill('SIGKILL');
console.log(failures ? `${failures} check(s) failed` : 'all browser checks passed');
process.exit(failures ? 1 : 0);
