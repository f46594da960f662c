  // The 2D view (rbsim/view/player2d.js, pasted into player.html by rbsim render).
  const DIMENSION = 2;
  const HELP = "drag: pan, wheel: zoom, arrows: step";
  // Each track: one trajectory. frames: Float32Array of (frame, body, [x, y, angle]).
  // contacts (when the run recorded them): per stored frame its points' count and first
  // row, and rows: Float32Array of (point, [x, y, nx, ny]) (m; unit normal).
  const tracks = data.tracks.map(function (t) {
    return {
      contacts: contactTable(t.contacts),
      label: t.label, names: t.names, types: t.types, overlay: t.overlay, n: t.names.length,
      frames: floats(t.frames),
      frameIndex: t.frame_index,  // track frame shown at each player frame
      polys: t.polys.map(function (p) { return { body: p[0], pts: p[1] }; }),
      circles: t.circles,          // [body, cx, cy, r]
      lines: t.lines,              // [body, ax, ay, bx, by]
    };
  });

  // Camera: world point (cx, cy) at the canvas centre, `scale` CSS pixels per metre.
  const cam = { cx: 0, cy: 0, scale: 1 };

  function fitView() {
    const v = data.view;  // [x0, y0, x1, y1], m
    cam.cx = (v[0] + v[2]) / 2;
    cam.cy = (v[1] + v[3]) / 2;
    cam.scale = Math.min(cssW / (v[2] - v[0]), cssH / (v[3] - v[1]));
  }


  function worldToScreen(x, y) {
    return [cssW / 2 + (x - cam.cx) * cam.scale, cssH / 2 - (y - cam.cy) * cam.scale];
  }
  function screenToWorld(px, py) {
    return [cam.cx + (px - cssW / 2) / cam.scale, cam.cy - (py - cssH / 2) / cam.scale];
  }

  // The pose of body b of track t at the current player frame: [x, y, cos, sin].
  function pose(t, b) {
    const k = t.frameIndex[frame];
    const o = (k * t.n + b) * 3;
    const a = t.frames[o + 2];
    return [t.frames[o], t.frames[o + 1], Math.cos(a), Math.sin(a)];
  }

  function drawTrack(t) {
    const n = t.n;
    const poses = new Float64Array(n * 4);
    for (let b = 0; b < n; b++) {
      const p = pose(t, b);
      poses[4 * b] = p[0]; poses[4 * b + 1] = p[1]; poses[4 * b + 2] = p[2]; poses[4 * b + 3] = p[3];
    }
    const s = cam.scale, ox = cssW / 2 - cam.cx * s, oy = cssH / 2 + cam.cy * s;
    const kinds = t.overlay ? ["overlay"] : ["static", "kinematic", "dynamic"];
    for (const kind of kinds) {
      const fill = new Path2D(), spokes = new Path2D(), lines = new Path2D();
      const wanted = function (b) { return t.overlay || t.types[b] === kind; };
      for (const p of t.polys) {
        const b = p.body;
        if (!wanted(b)) continue;
        const x = poses[4 * b], y = poses[4 * b + 1], c = poses[4 * b + 2], sn = poses[4 * b + 3];
        const pts = p.pts;
        for (let i = 0; i < pts.length; i += 2) {
          const wx = x + c * pts[i] - sn * pts[i + 1], wy = y + sn * pts[i] + c * pts[i + 1];
          if (i === 0) fill.moveTo(ox + wx * s, oy - wy * s); else fill.lineTo(ox + wx * s, oy - wy * s);
        }
        fill.closePath();
      }
      for (const q of t.circles) {
        const b = q[0];
        if (!wanted(b)) continue;
        const x = poses[4 * b], y = poses[4 * b + 1], c = poses[4 * b + 2], sn = poses[4 * b + 3];
        const wx = x + c * q[1] - sn * q[2], wy = y + sn * q[1] + c * q[2];
        const px = ox + wx * s, py = oy - wy * s, r = q[3] * s;
        fill.moveTo(px + r, py);
        fill.arc(px, py, r, 0, 2 * Math.PI);
        spokes.moveTo(px, py);
        spokes.lineTo(px + c * r, py - sn * r);
      }
      for (const q of t.lines) {
        const b = q[0];
        if (!wanted(b)) continue;
        const x = poses[4 * b], y = poses[4 * b + 1], c = poses[4 * b + 2], sn = poses[4 * b + 3];
        lines.moveTo(ox + (x + c * q[1] - sn * q[2]) * s, oy - (y + sn * q[1] + c * q[2]) * s);
        lines.lineTo(ox + (x + c * q[3] - sn * q[4]) * s, oy - (y + sn * q[3] + c * q[4]) * s);
      }
      const edge = colours[kind + "_edge"];
      if (!t.overlay) {
        ctx.fillStyle = colours[kind + "_fill"];
        ctx.fill(fill);
      }
      ctx.lineWidth = t.overlay ? 1.5 : 1;
      ctx.strokeStyle = edge;
      ctx.stroke(fill);
      ctx.lineWidth = 1.5;
      ctx.strokeStyle = t.overlay ? edge : colours.static_edge;
      ctx.stroke(lines);
      ctx.lineWidth = 1.2;
      ctx.strokeStyle = t.overlay ? edge : colours.dynamic_edge;
      ctx.stroke(spokes);
    }
  }


  // The contact points of track t at the current frame on the screen: [dots [x, y],
  // normals [x0, y0, x1, y1]] (CSS pixels; a normal data.contact_length m long).
  function contactPixels(t) {
    const c = t.contacts, dots = [], normals = [];
    if (!c) return [dots, normals];
    const k = t.frameIndex[frame], rows = c.rows, len = data.contact_length;
    for (let i = c.start[k], end = c.start[k] + c.count[k]; i < end; i++) {
      const o = 4 * i, p = worldToScreen(rows[o], rows[o + 1]);
      const q = worldToScreen(rows[o] + len * rows[o + 2], rows[o + 1] + len * rows[o + 3]);
      dots.push(p);
      normals.push([p[0], p[1], q[0], q[1]]);
    }
    return [dots, normals];
  }

  function drawScene() {
    for (const t of tracks) drawTrack(t);
  }

  // --- hit testing for names on hover -------------------------------------------------
  function inPolygon(px, py, pts) {  // even-odd rule, body-frame points
    let inside = false;
    for (let i = 0, j = pts.length - 2; i < pts.length; j = i, i += 2) {
      const xi = pts[i], yi = pts[i + 1], xj = pts[j], yj = pts[j + 1];
      if ((yi > py) !== (yj > py) && px < ((xj - xi) * (py - yi)) / (yj - yi) + xi) inside = !inside;
    }
    return inside;
  }
  function segmentDistance(px, py, ax, ay, bx, by) {
    const dx = bx - ax, dy = by - ay, len2 = dx * dx + dy * dy;
    let u = len2 > 0 ? ((px - ax) * dx + (py - ay) * dy) / len2 : 0;
    u = Math.max(0, Math.min(1, u));
    return Math.hypot(px - ax - u * dx, py - ay - u * dy);
  }
  // The track and body under world point (wx, wy): overlay first (drawn on top).
  function hit(wx, wy) {
    const slack = 4 / cam.scale;  // m: four pixels around thin lines
    for (let ti = tracks.length - 1; ti >= 0; ti--) {
      const t = tracks[ti];
      const found = function (b) {
        const p = pose(t, b);
        const dx = wx - p[0], dy = wy - p[1];
        return [p[2] * dx + p[3] * dy, -p[3] * dx + p[2] * dy];  // into the body frame
      };
      let best = -1;
      for (const q of t.circles) {
        const l = found(q[0]);
        if (Math.hypot(l[0] - q[1], l[1] - q[2]) <= q[3]) best = q[0];
      }
      for (const p of t.polys) {
        const l = found(p.body);
        if (inPolygon(l[0], l[1], p.pts)) best = p.body;
      }
      if (best < 0) {
        for (const q of t.lines) {
          const l = found(q[0]);
          if (segmentDistance(l[0], l[1], q[1], q[2], q[3], q[4]) <= slack) best = q[0];
        }
      }
      if (best >= 0) return [t, best];
    }
    return null;
  }
  function hitAt(px, py) {
    const w = screenToWorld(px, py);
    return hit(w[0], w[1]);
  }
  function tipText(t, b) {
    const p = pose(t, b);
    const ang = Math.atan2(p[3], p[2]);
    return t.names[b] + "  (" + t.types[b] + ")\n" + t.label +
      "\nx " + p[0].toFixed(3) + " m  y " + p[1].toFixed(3) + " m  angle " + ang.toFixed(3) + " rad";
  }
  function zoomAt(px, py, factor) {
    const before = screenToWorld(px, py);
    cam.scale = Math.min(1e7, Math.max(1e-6, cam.scale * factor));
    const after = screenToWorld(px, py);
    cam.cx += before[0] - after[0];
    cam.cy += before[1] - after[1];
    requestDraw();
  }
  function dragStart(e) { return [e.clientX, e.clientY, cam.cx, cam.cy]; }
  function dragMove(d, e) {
    cam.cx = d[2] - (e.clientX - d[0]) / cam.scale;
    cam.cy = d[3] + (e.clientY - d[1]) / cam.scale;
  }
  const viewApi = {
    worldToScreen: worldToScreen,
    bodyName: function (wx, wy) { const h = hit(wx, wy); return h ? h[0].names[h[1]] : null; },
  };
