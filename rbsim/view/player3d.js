  // The 3D view (rbsim/view/player3d.js, pasted into player.html by rbsim render): the
  // shapes as flat faces, placed per frame by each body's origin and quaternion, shaded
  // flat from one light and painted far to near (back faces culled) over the ground,
  // seen by a camera that orbits its target. The same camera and light as the GIF
  // (rbsim/view/mesh.py).
  const DIMENSION = 3;
  const HELP = "drag: orbit, shift-drag or right-drag: pan, wheel: zoom, arrows: step";
  const SHADES = 64;  // brightness steps of each colour (each a cached fill style)
  // Depth of the near plane, as a fraction of the camera's distance to its target:
  // nearer points are not drawn (nor faces reaching them; the ground is clipped there).
  const NEAR_FRACTION = 0.05;
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
  // qy, qz]); pts: body-frame points (m) of every shape's faces, ptBody their body;
  // faces: point indices, face i's from faceStart[i] to faceStart[i + 1], counter-
  // clockwise seen from outside; outlined[i]: its edges are drawn (boxes and hulls).
  // contacts (when the run recorded them): per stored frame its points' count and first
  // row, and rows: Float32Array of (point, [x, y, z, nx, ny, nz]) (m; unit normal).
  const tracks = data.tracks.map(function (t) {
    const pts = Float64Array.from(t.points), ptBody = Int32Array.from(t.point_body);
    const faces = Int32Array.from(t.faces), m = t.face_size.length;
    const faceStart = new Int32Array(m + 1), faceBody = new Int32Array(m);
    for (let i = 0; i < m; i++) {
      faceStart[i + 1] = faceStart[i] + t.face_size[i];
      faceBody[i] = ptBody[faces[faceStart[i]]];
    }
    const p = pts.length / 3;
    return {
      label: t.label, names: t.names, types: t.types, overlay: t.overlay, n: t.names.length,
      frames: floats(t.frames), frameIndex: t.frame_index,
      pts: pts, ptBody: ptBody, faces: faces, faceStart: faceStart, faceBody: faceBody,
      outlined: Uint8Array.from(t.face_outlined),
      world: new Float64Array(3 * p), scr: new Float64Array(2 * p), depth: new Float64Array(p),
      contacts: contactTable(t.contacts),
    };
  });

  // Camera: orbits `target` (m) at `distance` m, turned `yaw` rad about y from +z and
  // raised `pitch` rad above the horizontal; `fov` the vertical field of view, rad.
  const cam = { target: [0, 0, 0], distance: 10, yaw: 0, pitch: 0, fov: 0.7 };
  let eye = [0, 0, 0], right = [1, 0, 0], up = [0, 1, 0], fwd = [0, 0, -1], focal = 1, near = 0.5;

  // The camera at the first yaw and pitch, aimed at the centre of the box to show and
  // just far enough back to show its eight corners (as mesh.py's fit_distance).
  function fitView() {
    const c = data.camera, box = c.box;  // box: lo (3), hi (3), m
    cam.target = [0, 1, 2].map(function (i) { return (box[i] + box[i + 3]) / 2; });
    cam.yaw = c.yaw; cam.pitch = c.pitch; cam.fov = c.fov; cam.distance = 1;
    updateBasis();
    const ty = Math.tan(c.fov / 2), tx = ty * cssW / cssH;
    let d = 0;
    for (let k = 0; k < 8; k++) {
      const rel = [0, 1, 2].map(function (i) {
        return ((k >> i) & 1 ? box[i + 3] : box[i]) - cam.target[i];
      });
      const dot = function (v) { return rel[0] * v[0] + rel[1] * v[1] + rel[2] * v[2]; };
      const x = dot(right), y = dot(up), z = dot(fwd);
      d = Math.max(d, Math.abs(x) / tx - z, Math.abs(y) / ty - z);
    }
    cam.distance = d;
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
    near = NEAR_FRACTION * cam.distance;
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

  // The faces of the last picture, far to near: per track [track, face indices], for
  // names on hover.
  let drawn = [];

  // Faces of track t facing the camera and wholly in front of it, far to near, with
  // their brightness: [indices, brightness].
  function visible(t) {
    const faces = t.faces, fs = t.faceStart, w = t.world, depth = t.depth, m = fs.length - 1;
    const keep = [], key = new Float64Array(m), bright = new Float64Array(m);
    for (let i = 0; i < m; i++) {
      let behind = false, sum = 0;
      for (let j = fs[i]; j < fs[i + 1]; j++) {
        if (depth[faces[j]] <= near) { behind = true; break; }
        sum += depth[faces[j]];
      }
      if (behind) continue;
      const a = 3 * faces[fs[i]], b = 3 * faces[fs[i] + 1], c = 3 * faces[fs[i] + 2];
      const ux = w[b] - w[a], uy = w[b + 1] - w[a + 1], uz = w[b + 2] - w[a + 2];
      const vx = w[c] - w[a], vy = w[c + 1] - w[a + 1], vz = w[c + 2] - w[a + 2];
      const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
      const len = Math.hypot(nx, ny, nz);
      if (len === 0) continue;
      if (nx * (w[a] - eye[0]) + ny * (w[a + 1] - eye[1]) + nz * (w[a + 2] - eye[2]) >= 0) continue;
      const lit = Math.max(0, (nx * light[0] + ny * light[1] + nz * light[2]) / len);
      bright[i] = ambient + (1 - ambient) * lit;  // turned away from the light: ambient
      key[i] = sum / (fs[i + 1] - fs[i]);
      keep.push(i);
    }
    keep.sort(function (i, j) { return key[j] - key[i]; });
    return [keep, bright];
  }
  function facePath(path, t, i) {
    const scr = t.scr, faces = t.faces, fs = t.faceStart;
    for (let j = fs[i]; j < fs[i + 1]; j++) {
      const p = 2 * faces[j];
      if (j === fs[i]) path.moveTo(scr[p], scr[p + 1]); else path.lineTo(scr[p], scr[p + 1]);
    }
    path.closePath();
  }

  // The part beyond the near plane (depth > near) of the world polygon pts ([x, y, z]
  // each; a segment when `closed` is false), as screen points (one plane's clipping).
  function clipNear(pts, closed) {
    const out = [], n = pts.length, depth = pts.map(function (p) {
      return (p[0] - eye[0]) * fwd[0] + (p[1] - eye[1]) * fwd[1] + (p[2] - eye[2]) * fwd[2];
    });
    for (let i = 0; i < (closed ? n : n - 1); i++) {
      const j = (i + 1) % n, a = pts[i], b = pts[j];
      if (depth[i] > near) out.push(a);
      if ((depth[i] > near) !== (depth[j] > near)) {  // the edge crosses the near plane
        const u = (near - depth[i]) / (depth[j] - depth[i]);
        out.push([a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1]), a[2] + u * (b[2] - a[2])]);
      }
    }
    if (!closed && depth[n - 1] > near) out.push(pts[n - 1]);
    return out.map(function (p) { return project(p[0], p[1], p[2]); });
  }
  function drawGround() {
    const q = ground.quads, l = ground.lines;
    ctx.fillStyle = colours.ground_fill;
    for (let i = 0; i < q.length; i += 12) {
      const p = clipNear([0, 1, 2, 3].map(function (k) { return q.slice(i + 3 * k, i + 3 * k + 3); }), true);
      if (p.length < 3) continue;
      ctx.beginPath();
      ctx.moveTo(p[0][0], p[0][1]);
      for (let k = 1; k < p.length; k++) ctx.lineTo(p[k][0], p[k][1]);
      ctx.closePath();
      ctx.fill();
    }
    const grid = new Path2D();
    for (let i = 0; i < l.length; i += 6) {
      const p = clipNear([l.slice(i, i + 3), l.slice(i + 3, i + 6)], false);
      if (p.length < 2) continue;
      grid.moveTo(p[0][0], p[0][1]);
      grid.lineTo(p[1][0], p[1][1]);
    }
    ctx.lineWidth = 1;
    ctx.strokeStyle = colours.grid;
    ctx.stroke(grid);
  }

  // The contact points of track t at the current frame in front of the near plane, on
  // the screen: [dots [x, y], normals [x0, y0, x1, y1]] (CSS pixels; a normal is drawn
  // data.contact_length m long, when its tip is in front too).
  function contactPixels(t) {
    const c = t.contacts, dots = [], normals = [];
    if (!c) return [dots, normals];
    updateBasis();
    const k = t.frameIndex[frame], rows = c.rows, len = data.contact_length;
    for (let i = c.start[k], end = c.start[k] + c.count[k]; i < end; i++) {
      const o = 6 * i, x = rows[o], y = rows[o + 1], z = rows[o + 2];
      const p = project(x, y, z);
      if (p[2] <= near) continue;
      dots.push([p[0], p[1]]);
      const q = project(x + len * rows[o + 3], y + len * rows[o + 4], z + len * rows[o + 5]);
      if (q[2] > near) normals.push([p[0], p[1], q[0], q[1]]);
    }
    return [dots, normals];
  }

  function drawScene() {
    updateBasis();
    drawGround();
    drawn = [];
    ctx.lineJoin = "round";
    for (const t of tracks) {
      placeTrack(t);
      const v = visible(t), order = v[0], bright = v[1];
      drawn.push([t, order]);
      if (t.overlay) {
        const wire = new Path2D();
        for (const i of order) facePath(wire, t, i);
        ctx.lineWidth = 0.8;
        ctx.strokeStyle = colours.overlay_edge;
        ctx.stroke(wire);
        continue;
      }
      let fill = null, edge = null, width = 0;  // set on the context only when they change
      for (const i of order) {
        const k = Math.round((bright[i] - ambient) / (1 - ambient) * (SHADES - 1));
        const type = t.types[t.faceBody[i]];
        const style = shadeStyles[type][k];
        ctx.beginPath();
        facePath(ctx, t, i);
        if (style !== fill) ctx.fillStyle = fill = style;
        ctx.fill();
        // boxes and hulls outlined; round shapes' facets edged in their own colour,
        // which hides the seams between them
        const w = t.outlined[i] ? 1 : 0.6, e = t.outlined[i] ? colours[type + "_edge"] : style;
        if (w !== width) ctx.lineWidth = width = w;
        if (e !== edge) ctx.strokeStyle = edge = e;
        ctx.stroke();
      }
    }
  }

  // --- names on hover: the nearest drawn face under the pointer --------------------------
  function inFace(px, py, t, i) {  // inside the convex polygon: on one side of every edge
    const s = t.scr, faces = t.faces, fs = t.faceStart;
    let pos = false, neg = false;
    for (let j = fs[i]; j < fs[i + 1]; j++) {
      const a = 2 * faces[j], b = 2 * faces[j + 1 < fs[i + 1] ? j + 1 : fs[i]];
      const cross = (s[b] - s[a]) * (py - s[a + 1]) - (s[b + 1] - s[a + 1]) * (px - s[a]);
      if (cross > 0) pos = true; else if (cross < 0) neg = true;
    }
    return !(pos && neg);
  }
  function hitAt(px, py) {
    for (let k = drawn.length - 1; k >= 0; k--) {  // the overlay is drawn last, on top
      const t = drawn[k][0], order = drawn[k][1];
      for (let j = order.length - 1; j >= 0; j--) {  // nearest first
        if (inFace(px, py, t, order[j])) return [t, t.faceBody[order[j]]];
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
    colours: colours,
  };
