#!/usr/bin/env node
// Times ONNX Runtime (CPU execution provider, from the npm package onnxruntime-node) on the authors' UP-LVSM x224
// forward exported by bench/official_x224.py --export-onnx FILE: batch 1, 5 views at 224x224 (2 inputs + 3
// targets), fp32. The inputs are the ones the export wrote to FILE.io/ (torch.rand images with seed 0,
// fx = fy = 0.9 * 224, cx = cy = 0.5 * 224, identity c2w — what uplvsm_bench's Inference/paper_x224 feeds).
// Session: intraOpNumThreads 2 (--threads), interOpNumThreads 1, sequential execution, graph optimisation level
// 'all', ORT's own thread pool settings otherwise (--no-spin sets session.intra_op.allow_spinning=0).
// Runs --warmup untimed runs (default 1, as uplvsm_bench does), then --time N timed runs (default 3), printing
// seconds per target view (run time / 3) of each, the median and the mean; --check prints the max abs difference
// between ORT's output and torch's (FILE.io/render.f32).
//
// Set-up (onnxruntime-node is not a dependency of this repository; its install script fetches GPU extras and
// fails offline, the CPU build ships in the package):
//   mkdir -p /tmp/ort && cd /tmp/ort && npm install onnxruntime-node --ignore-scripts
// Run (repository root):
//   OMP_NUM_THREADS=2 OMP_WAIT_POLICY=PASSIVE node bench/ort_x224.mjs /tmp/uplvsm_official_x224.onnx \
//     --ort-dir /tmp/ort --time 3 [--check]
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';
import { performance } from 'node:perf_hooks';

function usage(message) {
  if (message) console.error(`ort_x224: ${message}`);
  console.error('usage: node bench/ort_x224.mjs MODEL.onnx [--ort-dir DIR] [--time N] [--warmup N] [--threads N] '
    + '[--check] [--no-spin]');
  process.exit(2);
}

const args = { time: 3, warmup: 1, threads: 2, check: false, spin: true, ortDir: process.env.ORT_DIR || '' };
let model = '';
const argv = process.argv.slice(2);
for (let i = 0; i < argv.length; i++) {
  const a = argv[i];
  const value = () => { if (i + 1 >= argv.length) usage(`${a} needs a value`); return argv[++i]; };
  if (a === '--time') args.time = parseInt(value(), 10);
  else if (a === '--warmup') args.warmup = parseInt(value(), 10);
  else if (a === '--threads') args.threads = parseInt(value(), 10);
  else if (a === '--ort-dir') args.ortDir = value();
  else if (a === '--check') args.check = true;
  else if (a === '--no-spin') args.spin = false;
  else if (a === '-h' || a === '--help') usage('');
  else if (a.startsWith('--')) usage(`unknown option ${a}`);
  else if (!model) model = a;
  else usage(`unexpected argument ${a}`);
}
if (!model) usage('no model');
if (!(args.time >= 0) || !(args.warmup >= 0) || !(args.threads >= 1)) usage('bad --time/--warmup/--threads');

// onnxruntime-node from --ort-dir (an npm prefix such as /tmp/ort) or, without it, from Node's own resolution.
const require = createRequire(args.ortDir ? path.join(path.resolve(args.ortDir), 'package.json') : import.meta.url);
const ort = require('onnxruntime-node');

const log = (m) => console.error(`[ort_x224] ${m}`);
const ioDir = `${model}.io`;
const io = JSON.parse(fs.readFileSync(path.join(ioDir, 'io.json'), 'utf8'));
const targetViews = io.target_views;

function readF32(file, shape) {
  const buf = fs.readFileSync(path.join(ioDir, file));
  const count = shape.reduce((a, b) => a * b, 1);
  if (buf.length !== 4 * count) throw new Error(`${file}: ${buf.length} bytes, expected ${4 * count}`);
  const data = new Float32Array(count);
  new Uint8Array(data.buffer).set(buf);  // copy: the Buffer may not be 4-byte aligned
  return data;
}

const options = {
  executionProviders: ['cpu'],
  intraOpNumThreads: args.threads,
  interOpNumThreads: 1,
  executionMode: 'sequential',
  graphOptimizationLevel: 'all',
};
if (!args.spin) options.extra = { session: { intra_op: { allow_spinning: '0' } } };

const t0 = performance.now();
const session = await ort.InferenceSession.create(model, options);
log(`onnxruntime-node ${ort.env.versions?.node ?? ort.env.versions?.common ?? '?'}, ${args.threads} intra-op threads, `
  + `session created in ${((performance.now() - t0) / 1000).toFixed(1)} s; inputs ${session.inputNames.join(', ')}`);

const feeds = {};
for (const name of session.inputNames) {
  const spec = io.inputs.find((x) => x.name === name);
  if (!spec) throw new Error(`model input ${name} not in ${ioDir}/io.json`);
  feeds[name] = new ort.Tensor('float32', readF32(spec.file, spec.shape), spec.shape);
}
const outputName = session.outputNames.includes('render') ? 'render' : session.outputNames[0];

async function run() {
  const result = await session.run(feeds);
  return result[outputName];
}

let out = null;
for (let i = 0; i < args.warmup; i++) {
  const s = performance.now();
  out = await run();
  log(`warm-up ${i}: ${((performance.now() - s) / 1000 / targetViews).toFixed(4)} s/view`);
}
const times = [];
for (let i = 0; i < args.time; i++) {
  const s = performance.now();
  out = await run();
  times.push((performance.now() - s) / 1000 / targetViews);
  console.log(`run ${i} ${times[i].toFixed(4)} s/view`);
}
if (times.length) {
  const sorted = [...times].sort((a, b) => a - b);
  const mid = sorted.length >> 1;
  const median = sorted.length % 2 ? sorted[mid] : (sorted[mid - 1] + sorted[mid]) / 2;
  console.log(`median ${median.toFixed(4)} s/view`);
  console.log(`mean ${(times.reduce((a, b) => a + b, 0) / times.length).toFixed(4)} s/view`);
}
if (args.check) {
  if (!out) out = await run();
  const expected = readF32(io.output.file, io.output.shape);
  if (out.dims.join('x') !== io.output.shape.join('x')) {
    throw new Error(`output shape ${out.dims} != torch's ${io.output.shape}`);
  }
  let maxAbs = 0;
  for (let i = 0; i < expected.length; i++) {
    const d = Math.abs(out.data[i] - expected[i]);
    if (!(d <= maxAbs)) maxAbs = d;  // NaN propagates
  }
  console.log(`max_abs_diff onnxruntime-node vs torch ${maxAbs.toExponential(3)}`);
}
