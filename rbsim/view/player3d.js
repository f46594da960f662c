  // The 3D view (rbsim/view/player3d.js, pasted into player.html by rbsim render): the
  // shapes as triangles, placed per frame by each body's origin and quaternion, shaded
  // flat from one light and painted far to near (back faces culled) over the ground,
  // seen by a camera that orbits its target. The same camera and light as the GIF
  // (rbsim/view/mesh.py).
  const DIMENSION = 3;
  const HELP = "drag: orbit, shift-drag or right-drag: pan, wheel: zoom, arrows: step";
  const SHADES = 64;  // brightness steps of each colour (each a cached fill style)
  const NEAR = 1e-3;  // m: points nearer than this to the camera's plane are not drawn
  const light = data.light, ambient = data.ambient, ground = data.ground;

  function rgbOf(hex) {
    return [1, 3, 5].map(function (i) { return parseInt(hex.slice(i, i + 2), 16); });
  }
  // SHADES fill styles of colour `hex`, from brightness `ambient` to 1.
  function shadeTable(hex) {
    const c = rgbOf(hex), out = [];
    for (let k = 0; k < SHADES; k++) {
      const b = ambient + (1 - ambient) * k / (SHADES - 1);
      out.push("rgb(" + Math.round(c[0] * b) + "," + Math.round(c[1] * b) + "," + Math.round(c[2] * b) + ")");
    }
    return out;
  }
  const shadeStyles = {};
  for (const kind of ["dynamic", "static", "kinematic"]) shadeStyles[kind] = shadeTable(colours[kind + "_fill"]);

  // Each track: one trajectory. frames: Float32Array of (frame, body, [x, y, z, qw, qx,
  // qy, qz]); pts: body-frame points (m) of every shape's triangles, ptBody their body;
  // tris: point indices, three per triangle, counter-clockwise seen from outside.
  const tracks = data.tracks.map(function (t) {
    const pts = Float64Array.from(t.points), ptBody = Int32Array.from(t.point_body);
    const tris = Int32Array.from(t.tris), m = tris.length / 3;
    const triBody = new Int32Array(m);
    for (let i = 0; i < m; i++) triBody[i] = ptBody[tris[3 * i]];
    const p = pts.length / 3;
    return {
      label: t.label, names: t.names, types: t.types, overlay: t.overlay, n: t.names.length,
      frames: floats(t.frames), frameIndex: t.frame_index,
      pts: pts, ptBody: ptBody, tris: tris, triBody: triBody,
      world: new Float64Array(3 * p), scr: new Float64Array(2 * p), depth: new Float64Array(p),
    };
  });

  // Camera: orbits `target` (m) at `distance` m, turned `yaw` rad about y from +z and
  // raised `pitch` rad above the horizontal; `fov` the vertical field of view, rad.
  const cam = { target: [0, 0, 0], distance: 10, yaw: 0, pitch: 0, fov: 0.7 };
  let eye = [0, 0, 0], right = [1, 0, 0], up = [0, 1, 0], fwd = [0, 0, -1], focal = 1;

  function fitView() {
    const c = data.camera;  // target, radius (m) of the sphere to show, yaw, pitch, fov
    cam.target = c.target.slice();
    cam.yaw = c.yaw; cam.pitch = c.pitch; cam.fov = c.fov;
    const half = c.fov / 2, halfW = Math.atan(Math.tan(half) * cssW / cssH);
    cam.distance = c.radius / Math.sin(Math.min(half, halfW));
  }
  function updateBasis() {
    const cp = Math.cos(cam.pitch), sp = Math.sin(cam.pitch);
    const cy = Math.cos(cam.yaw), sy = Math.sin(cam.yaw);
    const back = [cp * sy, sp, cp * cy];
    eye = [0, 1, 2].map(function (i) { return cam.target[i] + cam.distance * back[i]; });
    fwd = [-back[0], -back[1], -back[2]];
    right = [cy, 0, -sy];
    up = [right[1] * fwd[2] - right[2] * fwd[1], right[2] * fwd[0] - right[0] * fwd[2],
          right[0] * fwd[1] - right[1] * fwd[0]];
    focal = (cssH / 2) / Math.tan(cam.fov / 2);
  }
  // CSS pixels (x right, y down from the canvas's top-left corner) and depth (m) of a
  // world point.
  function worldToScreen(x, y, z) {
    updateBasis();
    return project(x, y, z);
  }
  function project(x, y, z) {
    const rx = x - eye[0], ry = y - eye[1], rz = z - eye[2];
    const d = rx * fwd[0] + ry * fwd[1] + rz * fwd[2];
    const zs = d > 1e-9 ? d : 1e-9;
    return [cssW / 2 + focal * (rx * right[0] + ry * right[1] + rz * right[2]) / zs,
            cssH / 2 - focal * (rx * up[0] + ry * up[1] + rz * up[2]) / zs, d];
  }

  // The pose of body b of track t at the current player frame: [x, y, z, qw, qx, qy, qz].
  function pose(t, b) {
    const o = (t.frameIndex[frame] * t.n + b) * 7;
    return Array.prototype.slice.call(t.frames, o, o + 7);
  }

  // Places and projects every point of track t at the current frame.
  function placeTrack(t) {
    const f = t.frames, base = t.frameIndex[frame] * t.n * 7, pts = t.pts;
    const world = t.world, scr = t.scr, depth = t.depth;
    let lastBody = -1, px = 0, py = 0, pz = 0;
    let r00 = 1, r01 = 0, r02 = 0, r10 = 0, r11 = 1, r12 = 0, r20 = 0, r21 = 0, r22 = 1;
    for (let i = 0, p = pts.length / 3; i < p; i++) {
      const b = t.ptBody[i];
      if (b !== lastBody) {
        const o = base + 7 * b;
        px = f[o]; py = f[o + 1]; pz = f[o + 2];
        let w = f[o + 3], x = f[o + 4], y = f[o + 5], z = f[o + 6];
        const norm = Math.hypot(w, x, y, z) || 1;
        w /= norm; x /= norm; y /= norm; z /= norm;
        r00 = 1 - 2 * (y * y + z * z); r01 = 2 * (x * y - w * z); r02 = 2 * (x * z + w * y);
        r10 = 2 * (x * y + w * z); r11 = 1 - 2 * (x * x + z * z); r12 = 2 * (y * z - w * x);
        r20 = 2 * (x * z - w * y); r21 = 2 * (y * z + w * x); r22 = 1 - 2 * (x * x + y * y);
        lastBody = b;
      }
      const vx = pts[3 * i], vy = pts[3 * i + 1], vz = pts[3 * i + 2];
      const wx = px + r00 * vx + r01 * vy + r02 * vz;
      const wy = py + r10 * vx + r11 * vy + r12 * vz;
      const wz = pz + r20 * vx + r21 * vy + r22 * vz;
      world[3 * i] = wx; world[3 * i + 1] = wy; world[3 * i + 2] = wz;
      // project(wx, wy, wz), inline: this loop runs for every point of every frame
      const rx = wx - eye[0], ry = wy - eye[1], rz = wz - eye[2];
      const d = rx * fwd[0] + ry * fwd[1] + rz * fwd[2], zs = d > 1e-9 ? d : 1e-9;
      scr[2 * i] = cssW / 2 + focal * (rx * right[0] + ry * right[1] + rz * right[2]) / zs;
      scr[2 * i + 1] = cssH / 2 - focal * (rx * up[0] + ry * up[1] + rz * up[2]) / zs;
      depth[i] = d;
    }
  }

  // The triangles of the last picture, near to far last: per track the indices drawn
  // (for names on hover), painted in this order.
  let drawn = [];

  // Triangles of track t facing the camera and wholly in front of it, far to near, with
  // their brightness: [indices, brightness].
  function visible(t) {
    const tris = t.tris, w = t.world, depth = t.depth, m = tris.length / 3;
    const keep = [], key = new Float64Array(m), bright = new Float64Array(m);
    for (let i = 0; i < m; i++) {
      const a = tris[3 * i], b = tris[3 * i + 1], c = tris[3 * i + 2];
      if (depth[a] <= NEAR || depth[b] <= NEAR || depth[c] <= NEAR) continue;
      const ux = w[3 * b] - w[3 * a], uy = w[3 * b + 1] - w[3 * a + 1], uz = w[3 * b + 2] - w[3 * a + 2];
      const vx = w[3 * c] - w[3 * a], vy = w[3 * c + 1] - w[3 * a + 1], vz = w[3 * c + 2] - w[3 * a + 2];
      const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
      const len = Math.hypot(nx, ny, nz);
      if (len === 0) continue;
      const cx = (w[3 * a] + w[3 * b] + w[3 * c]) / 3 - eye[0];
      const cy = (w[3 * a + 1] + w[3 * b + 1] + w[3 * c + 1]) / 3 - eye[1];
      const cz = (w[3 * a + 2] + w[3 * b + 2] + w[3 * c + 2]) / 3 - eye[2];
      if (nx * cx + ny * cy + nz * cz >= 0) continue;  // turned away from the camera
      const lit = Math.max(0, (nx * light[0] + ny * light[1] + nz * light[2]) / len);
      bright[i] = ambient + (1 - ambient) * lit;
      key[i] = depth[a] + depth[b] + depth[c];
      keep.push(i);
    }
    keep.sort(function (i, j) { return key[j] - key[i]; });
    return [keep, bright];
  }

  function drawGround() {
    const q = ground.quads, l = ground.lines;
    ctx.fillStyle = colours.ground_fill;
    for (let i = 0; i < q.length; i += 12) {
      const p = [];
      for (let k = 0; k < 4; k++) p.push(project(q[i + 3 * k], q[i + 3 * k + 1], q[i + 3 * k + 2]));
      if (p.some(function (s) { return s[2] <= NEAR; })) continue;
      ctx.beginPath();
      ctx.moveTo(p[0][0], p[0][1]);
      for (let k = 1; k < 4; k++) ctx.lineTo(p[k][0], p[k][1]);
      ctx.closePath();
      ctx.fill();
    }
    const grid = new Path2D();
    for (let i = 0; i < l.length; i += 6) {
      const a = project(l[i], l[i + 1], l[i + 2]), b = project(l[i + 3], l[i + 4], l[i + 5]);
      if (a[2] <= NEAR || b[2] <= NEAR) continue;
      grid.moveTo(a[0], a[1]);
      grid.lineTo(b[0], b[1]);
    }
    ctx.lineWidth = 1;
    ctx.strokeStyle = colours.grid;
    ctx.stroke(grid);
  }

  function drawScene() {
    updateBasis();
    drawGround();
    drawn = [];
    ctx.lineJoin = "round";
    for (const t of tracks) {
      placeTrack(t);
      const v = visible(t), order = v[0], bright = v[1], scr = t.scr, tris = t.tris;
      drawn.push([t, order]);
      if (t.overlay) {
        const wire = new Path2D();
        for (const i of order) {
          const a = 2 * tris[3 * i], b = 2 * tris[3 * i + 1], c = 2 * tris[3 * i + 2];
          wire.moveTo(scr[a], scr[a + 1]); wire.lineTo(scr[b], scr[b + 1]);
          wire.lineTo(scr[c], scr[c + 1]); wire.closePath();
        }
        ctx.lineWidth = 0.8;
        ctx.strokeStyle = colours.overlay_edge;
        ctx.stroke(wire);
        continue;
      }
      ctx.lineWidth = 0.6;  // each triangle's edge in its own colour hides the seams
      for (const i of order) {
        const a = 2 * tris[3 * i], b = 2 * tris[3 * i + 1], c = 2 * tris[3 * i + 2];
        const k = Math.round((bright[i] - ambient) / (1 - ambient) * (SHADES - 1));
        const style = shadeStyles[t.types[t.triBody[i]]][k];
        ctx.beginPath();
        ctx.moveTo(scr[a], scr[a + 1]); ctx.lineTo(scr[b], scr[b + 1]); ctx.lineTo(scr[c], scr[c + 1]);
        ctx.closePath();
        ctx.fillStyle = style;
        ctx.strokeStyle = style;
        ctx.fill();
        ctx.stroke();
      }
    }
  }

  // --- names on hover: the nearest drawn triangle under the pointer ----------------------
  function inTriangle(px, py, s, a, b, c) {
    const d1 = (px - s[b]) * (s[a + 1] - s[b + 1]) - (s[a] - s[b]) * (py - s[b + 1]);
    const d2 = (px - s[c]) * (s[b + 1] - s[c + 1]) - (s[b] - s[c]) * (py - s[c + 1]);
    const d3 = (px - s[a]) * (s[c + 1] - s[a + 1]) - (s[c] - s[a]) * (py - s[a + 1]);
    return !((d1 < 0 || d2 < 0 || d3 < 0) && (d1 > 0 || d2 > 0 || d3 > 0));
  }
  function hitAt(px, py) {
    for (let k = drawn.length - 1; k >= 0; k--) {  // the overlay is drawn last, on top
      const t = drawn[k][0], order = drawn[k][1], tris = t.tris;
      for (let j = order.length - 1; j >= 0; j--) {  // nearest first
        const i = order[j];
        if (inTriangle(px, py, t.scr, 2 * tris[3 * i], 2 * tris[3 * i + 1], 2 * tris[3 * i + 2])) {
          return [t, t.triBody[i]];
        }
      }
    }
    return null;
  }
  function tipText(t, b) {
    const p = pose(t, b);
    const w = Math.min(1, Math.abs(p[3]) / (Math.hypot(p[3], p[4], p[5], p[6]) || 1));
    return t.names[b] + "  (" + t.types[b] + ")\n" + t.label +
      "\nx " + p[0].toFixed(3) + " m  y " + p[1].toFixed(3) + " m  z " + p[2].toFixed(3) +
      " m\nturned " + (2 * Math.acos(w)).toFixed(3) + " rad  q (" +
      p.slice(3).map(function (c) { return c.toFixed(3); }).join(", ") + ")";
  }

  // --- the camera with the mouse -------------------------------------------------------
  function zoomAt(_px, _py, factor) {
    cam.distance = Math.min(1e7, Math.max(1e-3, cam.distance / factor));
    requestDraw();
  }
  function dragStart(e) {
    return { x: e.clientX, y: e.clientY, yaw: cam.yaw, pitch: cam.pitch,
             target: cam.target.slice(), pan: e.shiftKey || e.button === 2 };
  }
  function dragMove(d, e) {
    const dx = e.clientX - d.x, dy = e.clientY - d.y;
    if (d.pan) {  // move the target with the pointer, in the camera's plane
      updateBasis();
      const metres = 2 * cam.distance * Math.tan(cam.fov / 2) / cssH;  // per pixel at the target
      for (let i = 0; i < 3; i++) cam.target[i] = d.target[i] - metres * (dx * right[i] - dy * up[i]);
    } else {
      cam.yaw = d.yaw - dx * 0.008;  // rad per pixel
      cam.pitch = Math.max(-1.55, Math.min(1.55, d.pitch + dy * 0.008));
    }
  }
  canvas.addEventListener("contextmenu", function (e) { e.preventDefault(); });

  const viewApi = {
    worldToScreen: function (x, y, z) { return worldToScreen(x, y, z).slice(0, 2); },
    bodyAt: function (px, py) { const h = hitAt(px, py); return h ? h[0].names[h[1]] : null; },
    camera: function () { return JSON.parse(JSON.stringify(cam)); },
    setCamera: function (c) { Object.assign(cam, c); draw(); },
  };
