// Camera poses as the model reads them: [tx, ty, tz, qx, qy, qz, qw] (scalar-last quaternion), camera-to-world in
// OpenCV axes (x right, y down, z forward). Interpolation matches `uplvsm render` (linear translation, slerp).
'use strict';
const Cam = (() => {
  const qmul = (a, b) => [
    a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1],
    a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0],
    a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3],
    a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2],
  ];
  const qnorm = (q) => { const n = Math.hypot(...q) || 1; return q.map((v) => v / n); };
  const qaxis = (axis, angle) => {
    const s = Math.sin(angle / 2);
    return [axis[0] * s, axis[1] * s, axis[2] * s, Math.cos(angle / 2)];
  };
  // v' = q v q*
  const rotate = (q, v) => {
    const p = qmul(qmul(q, [v[0], v[1], v[2], 0]), [-q[0], -q[1], -q[2], q[3]]);
    return [p[0], p[1], p[2]];
  };
  const slerp = (a, b, t) => {
    let d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
    if (d < 0) { b = b.map((v) => -v); d = -d; }
    if (d > 0.9995) return qnorm(a.map((v, i) => v + t * (b[i] - v)));
    const th = Math.acos(d), s = Math.sin(th);
    const wa = Math.sin((1 - t) * th) / s, wb = Math.sin(t * th) / s;
    return a.map((v, i) => wa * v + wb * b[i]);
  };
  const interpolate = (p0, p1, t) => {
    const q = slerp(qnorm(p0.slice(3)), qnorm(p1.slice(3)), t);
    const pos = [0, 1, 2].map((i) => p0[i] * (1 - t) + p1[i] * t);
    return pos.concat(q);
  };
  const add = (a, b) => a.map((v, i) => v + b[i]);
  const scale = (a, s) => a.map((v) => v * s);

  // The viewer's camera: a base pose on the path between the inputs (slider t), then an orbit (yaw, pitch) around
  // a focus point `focus` units in front of it, a pan and a dolly in the orbiting camera's own axes. `unit` is the
  // length of one input baseline in the pose space (1 for real cameras).
  const compose = (base, c, unit) => {
    const orbit = qmul(qaxis([0, 1, 0], c.yaw), qaxis([1, 0, 0], c.pitch));
    const forward = rotate(orbit, [0, 0, 1]);
    let local = add([0, 0, c.focus], scale(forward, -c.focus));
    local = add(local, rotate(orbit, [c.panX, c.panY, c.dolly]));
    const q = qnorm(base.slice(3));
    const pos = add(base.slice(0, 3), rotate(q, scale(local, unit)));
    return pos.concat(qnorm(qmul(q, orbit)));
  };
  return { qmul, qnorm, qaxis, rotate, slerp, interpolate, compose };
})();
