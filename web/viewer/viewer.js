// The viewer page: scene picking (dataset list or two uploaded photos), the camera controls, frame requests to
// `uplvsm serve` (at most two in flight; the server drops a waiting frame that a newer one overtook, and the page
// only ever shows a newer frame than the one on screen), the camera plot, and recording a path as MP4 / JSON.
'use strict';
(() => {
  const $ = (id) => document.getElementById(id);
  const MAX_IN_FLIGHT = 2;
  const MAX_PATH = 600;
  const st = {
    info: null, session: null, space: 'latent', keys: null, unit: 1,
    cam: null, t: 0, override: null,
    seq: 0, shown: 0, inFlight: 0, dirty: false, frames: 0, dropped: 0, lastMs: null,
    recording: false, path: [], playing: false, current: null,
  };
  const freshCam = () => ({ yaw: 0, pitch: 0, panX: 0, panY: 0, dolly: 0, focus: Number($('focus').value) || 2 });
  st.cam = freshCam();

  function status(text, isError) {
    const el = $('status');
    el.textContent = text || '';
    el.classList.toggle('error', !!isError);
  }

  async function api(path, options) {
    const r = await fetch(path, options);
    if (!r.ok) {
      let msg = r.status + ' ' + r.statusText;
      try { msg = (await r.json()).error || msg; } catch (e) { /* not JSON */ }
      throw new Error(msg);
    }
    return r;
  }
  const postJson = (path, body) =>
    api(path, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body) });

  // ---- model and scenes --------------------------------------------------------------------------------------
  async function init() {
    st.info = await (await api('/api/info')).json();
    const i = st.info;
    $('model-info').textContent = `${i.config_name || 'model'} · ${i.image_size}×${i.image_size} · ` +
      `${(i.parameters / 1e6).toFixed(1)} M parameters · ${i.amp === 'bf16' ? 'bf16' : 'fp32'} · ` +
      (i.has_mapper ? 'camera mapper: real units' : 'no mapper: latent camera');
    $('presets').classList.toggle('hidden', !i.has_mapper);
    if (i.scenes > 0) await listScenes(); else showTab('upload');
    if (i.scenes === 0) $('tab-dataset').disabled = true;
  }

  async function listScenes() {
    const { scenes } = await (await api('/api/scenes')).json();
    const list = $('scene-list');
    list.textContent = '';
    for (const s of scenes) {
      const card = document.createElement('button');
      card.type = 'button';
      card.className = 'scene-card';
      card.dataset.id = s.id;
      card.title = s.name;
      const img = document.createElement('img');
      img.loading = 'lazy';
      img.src = s.thumbnail;
      img.alt = s.name;
      const name = document.createElement('span');
      name.textContent = s.name;
      card.append(img, name);
      card.addEventListener('click', () => openScene(s.id, card));
      list.append(card);
    }
  }

  async function openScene(id, card) {
    document.querySelectorAll('.scene-card').forEach((c) => c.classList.toggle('selected', c === card));
    status('encoding the scene…');
    try {
      useSession(await (await postJson('/api/sessions', { scene: id })).json());
    } catch (e) { status(e.message, true); }
  }

  function useSession(s) {
    st.session = s;
    st.space = s.has_mapper ? 'real' : 'latent';
    st.keys = st.space === 'real' ? s.key_real : s.key_latent;
    const d = st.keys[1].slice(0, 3).map((v, i) => v - st.keys[0][i]);
    st.unit = st.space === 'real' ? 1 : Math.max(Math.hypot(...d), 1e-3);
    $('input0').src = s.inputs[0] + '?' + s.session;
    $('input1').src = s.inputs[1] + '?' + s.session;
    $('placeholder').classList.add('hidden');
    $('mode-badge').textContent = st.space === 'real'
      ? (s.key_real_estimated
        ? 'real camera · input 2 placed by the mapper (residual ' + Number(s.key_real_residual).toFixed(3) + ')'
        : 'real camera · baseline units')
      : 'latent camera';
    $('plot-units').textContent = st.space === 'real' ? '(baselines)' : '(latent space)';
    st.path = [];
    st.shown = st.seq;
    updateRecordUi();
    reset();
    status(`${s.name}: ${s.width}×${s.height}, scene latents cached`);
    showPhotoNotes(s.photos);
  }
  // Uploads: how each photo was turned upright and where its field of view came from (EXIF, the FoV field, 60°).
  function showPhotoNotes(photos) {
    const list = $('photo-notes');
    list.textContent = '';
    for (const p of photos || []) {
      const li = document.createElement('li');
      li.textContent = p.note;
      list.append(li);
    }
  }

  // ---- camera ------------------------------------------------------------------------------------------------
  function pose() {
    if (st.override) return st.override;
    return Cam.compose(Cam.interpolate(st.keys[0], st.keys[1], st.t), st.cam, st.unit);
  }
  function reset() {
    st.cam = freshCam();
    st.t = 0;
    $('interp').value = 0;
    changed();
  }
  function changed() {
    if (!st.session) return;
    st.current = pose();
    if (st.recording) record(st.current);
    drawPlot();
    st.dirty = true;
    pump();
  }

  // ---- frames ------------------------------------------------------------------------------------------------
  function pump() {
    if (!st.session || !st.dirty || st.inFlight >= MAX_IN_FLIGHT) return;
    st.dirty = false;
    const seq = ++st.seq;
    st.inFlight++;
    requestFrame(st.current, seq).finally(() => { st.inFlight--; pump(); });
  }

  async function requestFrame(p, seq) {
    const sid = st.session.session;
    try {
      const r = await fetch(`/api/sessions/${sid}/frame`, {
        method: 'POST', headers: { 'Content-Type': 'application/json' },
        body: JSON.stringify({ pose: p, space: st.space, seq, format: $('png').checked ? 'png' : 'jpeg' }),
      });
      if (r.status === 204) { st.dropped++; return; }
      if (r.status === 404 && st.session && st.session.session === sid) {
        status('the session expired: pick the scene again', true);
        return;
      }
      if (!r.ok) throw new Error((await r.json()).error || r.statusText);
      const bitmap = await createImageBitmap(await r.blob());
      if (seq <= st.shown || !st.session || st.session.session !== sid) return;  // a newer frame is on screen
      st.shown = seq;
      st.frames++;
      st.lastMs = Number(r.headers.get('X-Render-Ms'));
      show(bitmap, seq);
    } catch (e) {
      status(e.message, true);
    }
  }

  function show(bitmap, seq) {
    const c = $('frame');
    const ctx = c.getContext('2d');
    ctx.imageSmoothingEnabled = $('smooth').checked;
    ctx.imageSmoothingQuality = 'high';
    const s = Math.min(c.width / bitmap.width, c.height / bitmap.height);
    const w = bitmap.width * s, h = bitmap.height * s;
    ctx.fillStyle = '#0b0d10';
    ctx.fillRect(0, 0, c.width, c.height);
    ctx.drawImage(bitmap, (c.width - w) / 2, (c.height - h) / 2, w, h);
    c.dataset.frames = String(st.frames);
    c.dataset.seq = String(seq);
    $('timing').textContent = `${st.lastMs.toFixed(0)} ms decoder · frame ${st.frames}` +
      (st.dropped ? ` · ${st.dropped} superseded` : '');
  }

  function drawPlot() {
    if (!st.session) return;
    Plot.draw($('plot'), { keys: st.keys, current: st.current, path: st.path, unit: st.unit });
  }

  // ---- input -------------------------------------------------------------------------------------------------
  function attachControls() {
    const c = $('frame');
    let drag = null;
    c.addEventListener('pointerdown', (e) => {
      drag = [e.clientX, e.clientY];
      c.setPointerCapture(e.pointerId);
      c.focus();
    });
    c.addEventListener('pointerup', () => { drag = null; });
    c.addEventListener('pointercancel', () => { drag = null; });
    c.addEventListener('pointermove', (e) => {
      if (!drag || st.playing) return;
      const k = 0.006;
      st.cam.yaw = clamp(st.cam.yaw + (e.clientX - drag[0]) * k, -3, 3);
      st.cam.pitch = clamp(st.cam.pitch - (e.clientY - drag[1]) * k, -1.4, 1.4);
      drag = [e.clientX, e.clientY];
      changed();
    });
    c.addEventListener('wheel', (e) => {
      e.preventDefault();
      if (st.playing) return;
      st.cam.dolly = clamp(st.cam.dolly - e.deltaY * 0.0015, -20, 20);
      changed();
    }, { passive: false });
    window.addEventListener('keydown', (e) => {
      if (!st.session || st.playing || e.target.tagName === 'INPUT') return;
      const step = 0.05;
      const moves = {
        ArrowLeft: ['panX', -step], a: ['panX', -step], ArrowRight: ['panX', step], d: ['panX', step],
        ArrowUp: ['panY', -step], w: ['panY', -step], ArrowDown: ['panY', step], s: ['panY', step],
        q: ['dolly', step], e: ['dolly', -step],
      };
      const m = moves[e.key];
      if (m) { st.cam[m[0]] += m[1]; changed(); e.preventDefault(); } else if (e.key === 'r') reset();
    });
    $('interp').addEventListener('input', (e) => { st.t = Number(e.target.value); changed(); });
    $('reset').addEventListener('click', reset);
    $('focus').addEventListener('change', () => { st.cam.focus = clamp(Number($('focus').value) || 2, 0.2, 20); changed(); });
    $('smooth').addEventListener('change', () => { st.dirty = true; pump(); });
    document.querySelectorAll('[data-preset]').forEach((b) => b.addEventListener('click', () => playPreset(b.dataset.preset)));
    Plot.attach($('plot'));
  }
  const clamp = (v, lo, hi) => Math.max(lo, Math.min(hi, v));

  // Presets: real cameras around input 1 (camera-control units), played frame by frame.
  async function playPreset(name) {
    if (!st.session || st.playing) return;
    st.playing = true;
    try {
      const focus = clamp(Number($('focus').value) || 2, 0.2, 20);
      const { poses } = await (await api(`/api/presets/${name}?frames=48&focus=${focus}`)).json();
      for (const p of poses) {
        st.override = p;
        st.current = p;
        if (st.recording) record(p);
        drawPlot();
        await requestFrame(p, ++st.seq);
      }
    } catch (e) {
      status(e.message, true);
    } finally {
      st.override = null;
      st.playing = false;
      changed();
    }
  }

  // ---- recording ---------------------------------------------------------------------------------------------
  function record(p) {
    const last = st.path[st.path.length - 1];
    if (last && last.every((v, i) => Math.abs(v - p[i]) < 1e-9)) return;
    if (st.path.length >= MAX_PATH) { toggleRecord(); status(`recording stopped at ${MAX_PATH} poses`); return; }
    st.path.push(p.slice());
    updateRecordUi();
  }
  function toggleRecord() {
    st.recording = !st.recording;
    if (st.recording) { st.path = []; if (st.current) record(st.current); }
    updateRecordUi();
  }
  function updateRecordUi() {
    const b = $('record');
    b.textContent = st.recording ? '■ Stop' : '● Record';
    b.classList.toggle('recording', st.recording);
    $('record-count').textContent = st.path.length ? `${st.path.length} poses` : '';
    const ready = !st.recording && st.path.length >= 2;
    $('download-json').disabled = !ready;
    $('download-mp4').disabled = !ready;
    drawPlot();
  }
  function download(blob, name) {
    const a = document.createElement('a');
    a.href = URL.createObjectURL(blob);
    a.download = name;
    document.body.append(a);
    a.click();
    setTimeout(() => { URL.revokeObjectURL(a.href); a.remove(); }, 1000);
  }
  // The JSON `uplvsm render --trajectory` reads: real cameras in input baselines, or latent poses.
  function downloadJson() {
    const doc = {
      units: st.space === 'real' ? 'baseline' : 'latent',
      frames: st.path.map((p) => ({ pose: p })),
      scene: st.session.name,
      note: 'uplvsm render --checkpoint CKPT ' + (st.session.name === 'upload' ? '--images A B' : '--data DIR') +
        ' --trajectory this_file.json --out DIR',
    };
    download(new Blob([JSON.stringify(doc, null, 1)], { type: 'application/json' }), 'camera_path.json');
  }
  async function downloadMp4() {
    const max = st.info.max_video_frames;
    const step = Math.max(1, Math.ceil(st.path.length / max));
    const poses = st.path.filter((_, i) => i % step === 0);
    status(`rendering ${poses.length} frames…`);
    $('download-mp4').disabled = true;
    try {
      const r = await postJson(`/api/sessions/${st.session.session}/video`, { poses, space: st.space, fps: 12 });
      download(await r.blob(), 'uplvsm_path.mp4');
      status(`MP4 of ${poses.length} frames downloaded`);
    } catch (e) {
      status(e.message, true);
    } finally {
      updateRecordUi();
    }
  }

  // ---- uploads -----------------------------------------------------------------------------------------------
  const photos = [null, null];
  function setPhoto(i, file) {
    if (!file) return;
    photos[i] = file;
    const drop = $('drop' + i);
    drop.style.backgroundImage = `url(${URL.createObjectURL(file)})`;
    drop.classList.add('filled');
    $('upload-go').disabled = !(photos[0] && photos[1]);
  }
  function attachUploads() {
    [0, 1].forEach((i) => {
      const drop = $('drop' + i);
      drop.querySelector('input').addEventListener('change', (e) => setPhoto(i, e.target.files[0]));
      drop.addEventListener('dragover', (e) => { e.preventDefault(); drop.classList.add('over'); });
      drop.addEventListener('dragleave', () => drop.classList.remove('over'));
      drop.addEventListener('drop', (e) => {
        e.preventDefault();
        drop.classList.remove('over');
        const files = [...e.dataTransfer.files].filter((f) => /image\/(png|jpeg)/.test(f.type));
        if (files.length >= 2) { setPhoto(0, files[0]); setPhoto(1, files[1]); } else setPhoto(i, files[0]);
      });
    });
    $('upload-go').addEventListener('click', async () => {
      const form = new FormData();
      form.append('image0', photos[0]);
      form.append('image1', photos[1]);
      form.append('fov', $('fov').value);
      status('uploading and encoding…');
      try {
        useSession(await (await api('/api/upload', { method: 'POST', body: form })).json());
      } catch (e) { status(e.message, true); }
    });
  }
  function showTab(name) {
    $('tab-dataset').classList.toggle('active', name === 'dataset');
    $('tab-upload').classList.toggle('active', name === 'upload');
    $('pane-dataset').classList.toggle('hidden', name !== 'dataset');
    $('pane-upload').classList.toggle('hidden', name !== 'upload');
  }

  $('tab-dataset').addEventListener('click', () => showTab('dataset'));
  $('tab-upload').addEventListener('click', () => showTab('upload'));
  $('record').addEventListener('click', toggleRecord);
  $('download-json').addEventListener('click', downloadJson);
  $('download-mp4').addEventListener('click', downloadMp4);
  attachControls();
  attachUploads();
  init().catch((e) => status(e.message, true));
})();
