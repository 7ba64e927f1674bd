// A small 3-D plot of the cameras: both inputs, the current view and the recorded path, as frustums seen from an
// angle the user can turn by dragging. Orthographic, fitted to the cameras shown.
'use strict';
const Plot = (() => {
  const colours = { in0: '#ff9f43', in1: '#54a0ff', cur: '#1dd1a1', path: '#c8d6e5' };
  let view = { yaw: -0.6, pitch: 0.45 };
  let last = null;

  // World (OpenCV, y down) -> plot view coordinates (x right, y up, z towards the viewer).
  const toView = (p, centre) => {
    const x = p[0] - centre[0], y = -(p[1] - centre[1]), z = p[2] - centre[2];
    const cy = Math.cos(view.yaw), sy = Math.sin(view.yaw), cp = Math.cos(view.pitch), sp = Math.sin(view.pitch);
    const x1 = cy * x + sy * z, z1 = -sy * x + cy * z;
    return [x1, cp * y - sp * z1, sp * y + cp * z1];
  };

  const frustum = (pose, size) => {
    const q = pose.slice(3), o = pose.slice(0, 3);
    const corners = [[-1, -0.75], [1, -0.75], [1, 0.75], [-1, 0.75]].map(([u, v]) =>
      Cam.rotate(q, [u * size * 0.6, v * size * 0.6, size]).map((d, i) => d + o[i]));
    const up = Cam.rotate(q, [0, -size * 0.9, size]).map((d, i) => d + o[i]);
    return { o, corners, up };
  };

  function draw(canvas, data) {
    last = { canvas, data };
    const ctx = canvas.getContext('2d');
    const W = canvas.width, H = canvas.height;
    ctx.clearRect(0, 0, W, H);
    if (!data || !data.keys) return;
    const poses = [data.keys[0], data.keys[1], data.current].concat(data.path || []).filter(Boolean);
    const centre = [0, 1, 2].map((i) => poses.reduce((s, p) => s + p[i], 0) / poses.length);
    const size = Math.max(0.25 * data.unit, 1e-3);
    const frusta = [[data.keys[0], 'in0'], [data.keys[1], 'in1'], [data.current, 'cur']]
      .filter(([p]) => p).map(([p, k]) => [frustum(p, size), k]);
    const pts = [];
    frusta.forEach(([f]) => pts.push(f.o, ...f.corners));
    (data.path || []).forEach((p) => pts.push(p.slice(0, 3)));
    const v = pts.map((p) => toView(p, centre));
    const ext = Math.max(1e-6, ...v.map((p) => Math.max(Math.abs(p[0]), Math.abs(p[1]))));
    const s = 0.42 * Math.min(W, H) / ext;
    const px = (p) => { const q = toView(p, centre); return [W / 2 + s * q[0], H / 2 - s * q[1]]; };

    // ground grid through the centre, for depth cues
    ctx.strokeStyle = 'rgba(255,255,255,0.07)';
    ctx.lineWidth = 1;
    const g = ext;
    for (let i = -4; i <= 4; i++) {
      const a = g * i / 4;
      line(ctx, px([centre[0] + a, centre[1], centre[2] - g]), px([centre[0] + a, centre[1], centre[2] + g]));
      line(ctx, px([centre[0] - g, centre[1], centre[2] + a]), px([centre[0] + g, centre[1], centre[2] + a]));
    }
    if (data.path && data.path.length > 1) {
      ctx.strokeStyle = colours.path;
      ctx.lineWidth = 1.5;
      ctx.beginPath();
      data.path.forEach((p, i) => { const [x, y] = px(p); if (i) ctx.lineTo(x, y); else ctx.moveTo(x, y); });
      ctx.stroke();
    }
    frusta.forEach(([f, k]) => {
      ctx.strokeStyle = colours[k];
      ctx.lineWidth = k === 'cur' ? 2.5 : 2;
      const o = px(f.o), c = f.corners.map(px);
      c.forEach((p) => line(ctx, o, p));
      for (let i = 0; i < 4; i++) line(ctx, c[i], c[(i + 1) % 4]);
      ctx.fillStyle = colours[k];
      const u = px(f.up);
      ctx.beginPath(); ctx.arc(u[0], u[1], 2.5, 0, 2 * Math.PI); ctx.fill();
      ctx.beginPath(); ctx.arc(o[0], o[1], 3.5, 0, 2 * Math.PI); ctx.fill();
    });
  }

  function line(ctx, a, b) { ctx.beginPath(); ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); ctx.stroke(); }

  function attach(canvas) {
    let drag = null;
    canvas.addEventListener('pointerdown', (e) => { drag = [e.clientX, e.clientY]; canvas.setPointerCapture(e.pointerId); });
    canvas.addEventListener('pointerup', () => { drag = null; });
    canvas.addEventListener('pointermove', (e) => {
      if (!drag) return;
      view.yaw += (e.clientX - drag[0]) * 0.01;
      view.pitch = Math.max(-1.5, Math.min(1.5, view.pitch + (e.clientY - drag[1]) * 0.01));
      drag = [e.clientX, e.clientY];
      if (last) draw(last.canvas, last.data);
    });
  }
  return { draw, attach };
})();
