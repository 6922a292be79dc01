/* parsel_eval.js: a parsel program evaluated in the browser (or in Node for tests).
 *
 * Mirrors parsel_core.program.evaluate for one set of parameter values:
 *   1. every op's amount: PARSEL_AMOUNTS[i](values), generated from the safe expression tree;
 *   2. part ops in program order, each the point map of parsel_core/ops.py on the corners
 *      of its targets (on a feature, only that feature's corners); ops without a map here
 *      (plugins') use the one generated from their transform, PARSEL_POINT_MAPS[i]; in a
 *      layered program (scene.layers) each layer runs on the rest corners and the layers'
 *      displacements add, then the outer layers (scene.outer) run in turn on that sum, each
 *      following op conjugated by its followed point's shift (scene.follows), as
 *      parsel_core.program._apply_part_ops does;
 *   3. group layouts (parsel_core/layout.py): instances of the first member as edited;
 *   4. meshes: each vertex holds its 8 trilinear weights in its part's rest hexahedron,
 *      so its position is one (m, 8) @ (8, 3) product with the evaluated corners;
 *   5. relations (brokenRelations): each relation's residual r0 + M d, d the members'
 *      corner displacements, with parsel_core.report's sliding contacts for attachments.
 * Corners are Float64Array(24) in canonical corner order (corner k at the bits of k).
 */
(function (root) {
  "use strict";

  function decodeBase64(text, Type) {
    var bytes;
    if (typeof atob === "function") {
      var binary = atob(text);
      bytes = new Uint8Array(binary.length);
      for (var i = 0; i < binary.length; i++) bytes[i] = binary.charCodeAt(i);
    } else {
      var buffer = Buffer.from(text, "base64");
      bytes = new Uint8Array(buffer.byteLength);
      bytes.set(buffer);
    }
    return new Type(bytes.buffer, 0, bytes.byteLength / Type.BYTES_PER_ELEMENT);
  }

  /* Trilinear weights (m * 8) of cube points uvw (m * 3): parsel_core.cage.cage_weights. */
  function trilinearWeights(uvw) {
    var m = uvw.length / 3, out = new Float64Array(m * 8);
    for (var i = 0; i < m; i++) {
      var u = uvw[3 * i], v = uvw[3 * i + 1], w = uvw[3 * i + 2];
      for (var k = 0; k < 8; k++) {
        var fu = (k >> 2) & 1 ? u : 1 - u, fv = (k >> 1) & 1 ? v : 1 - v, fw = k & 1 ? w : 1 - w;
        out[8 * i + k] = fu * fv * fw;
      }
    }
    return out;
  }

  /* The point maps of parsel_core/ops.py, on one point (x, y, z) -> out[0..2]. */
  var POINT_MAPS = {
    translate: function (q, a, pr, out) {
      var d = pr.dir;
      out[0] = q[0] + d[0] * a; out[1] = q[1] + d[1] * a; out[2] = q[2] + d[2] * a;
    },
    rotate: function (q, a, pr, out) {
      var o = pr.origin, n = pr.axis, c = Math.cos(a), s = Math.sin(a);
      var x = q[0] - o[0], y = q[1] - o[1], z = q[2] - o[2];
      var dot = x * n[0] + y * n[1] + z * n[2];
      var cx = n[1] * z - n[2] * y, cy = n[2] * x - n[0] * z, cz = n[0] * y - n[1] * x;
      out[0] = o[0] + (x * c + cx * s + dot * n[0] * (1 - c));
      out[1] = o[1] + (y * c + cy * s + dot * n[1] * (1 - c));
      out[2] = o[2] + (z * c + cz * s + dot * n[2] * (1 - c));
    },
    scale_1d: function (q, a, pr, out) {
      var o = pr.origin, d = pr.dir;
      var x = q[0] - o[0], y = q[1] - o[1], z = q[2] - o[2];
      var dot = x * d[0] + y * d[1] + z * d[2];
      out[0] = o[0] + x + dot * d[0] * a; out[1] = o[1] + y + dot * d[1] * a; out[2] = o[2] + z + dot * d[2] * a;
    },
    scale_2d: function (q, a, pr, out) {
      var o = pr.origin, n = pr.normal;
      var x = q[0] - o[0], y = q[1] - o[1], z = q[2] - o[2];
      var dot = x * n[0] + y * n[1] + z * n[2];
      var ax = dot * n[0], ay = dot * n[1], az = dot * n[2];
      out[0] = o[0] + (x - ax) * (1 + a) + ax;
      out[1] = o[1] + (y - ay) * (1 + a) + ay;
      out[2] = o[2] + (z - az) * (1 + a) + az;
    },
    scale_3d: function (q, a, pr, out) {
      var o = pr.origin;
      out[0] = o[0] + (q[0] - o[0]) * (1 + a);
      out[1] = o[1] + (q[1] - o[1]) * (1 + a);
      out[2] = o[2] + (q[2] - o[2]) * (1 + a);
    },
    shear: function (q, a, pr, out) {
      var o = pr.origin, n = pr.normal, d = pr.dir;
      var x = q[0] - o[0], y = q[1] - o[1], z = q[2] - o[2];
      var dot = x * n[0] + y * n[1] + z * n[2];
      out[0] = o[0] + x + dot * d[0] * a; out[1] = o[1] + y + dot * d[1] * a; out[2] = o[2] + z + dot * d[2] * a;
    },
    keep_fixed: function (q, a, pr, out) {
      out[0] = q[0]; out[1] = q[1]; out[2] = q[2];
    }
  };
  var ALL_CORNERS = [0, 1, 2, 3, 4, 5, 6, 7];

  /* generated: the op's point map from program.js (PARSEL_POINT_MAPS), for ops without a hand-written one. */
  function applyOp(op, corners, amount, generated) {
    var map = generated || POINT_MAPS[op.op], q = [0, 0, 0], out = [0, 0, 0];
    var which = op.corners || ALL_CORNERS;
    for (var i = 0; i < which.length; i++) {
      var k = which[i];
      q[0] = corners[3 * k]; q[1] = corners[3 * k + 1]; q[2] = corners[3 * k + 2];
      map(q, amount, op.params, out);
      corners[3 * k] = out[0]; corners[3 * k + 1] = out[1]; corners[3 * k + 2] = out[2];
    }
  }

  function centroid(c) {
    var s = [0, 0, 0];
    for (var k = 0; k < 8; k++) { s[0] += c[3 * k]; s[1] += c[3 * k + 1]; s[2] += c[3 * k + 2]; }
    return [s[0] / 8, s[1] / 8, s[2] / 8];
  }

  function weighted(weights, c) {
    var s = [0, 0, 0];
    for (var k = 0; k < 8; k++) {
      s[0] += weights[k] * c[3 * k]; s[1] += weights[k] * c[3 * k + 1]; s[2] += weights[k] * c[3 * k + 2];
    }
    return s;
  }

  function norm(v) { return Math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }
  function roundHalfUp(a) { return Math.floor(a + 0.5); }

  /* parsel_core.layout.translation_layout: instances as an array of Float64Array(24); instance j < k
     carries member j's deviation from the perfect row (translation_deviations). */
  function translationLayout(g, parent, members, amounts) {
    var k = g.members.length, first = members[0], mean = centroid(first);
    var restStep = g.rest_step, count = k, start, step, i, j;
    if (g.mode === "top_down") {
      start = weighted(g.anchor_weights[0], parent);
      var end = weighted(g.anchor_weights[1], parent);
      var span = [end[0] - start[0], end[1] - start[1], end[2] - start[2]];
      step = k > 1 ? [span[0] / (k - 1), span[1] / (k - 1), span[2] / (k - 1)] : [0, 0, 0];
      for (i = 0; i < g.ops.length; i++) {
        var a = amounts[g.ops[i].index];
        if (g.ops[i].op === "change_count") {
          count = Math.max(1, k + roundHalfUp(a));
          step = count > 1 ? [span[0] / (count - 1), span[1] / (count - 1), span[2] / (count - 1)] : [0, 0, 0];
        } else {
          var length = norm(span), restLength = norm(restStep);
          var direction = length > 0 ? [span[0] / length, span[1] / length, span[2] / length]
            : [restStep[0] / Math.max(restLength, 1e-300), restStep[1] / Math.max(restLength, 1e-300),
              restStep[2] / Math.max(restLength, 1e-300)];
          var scale = restLength * (1 + a);
          step = [direction[0] * scale, direction[1] * scale, direction[2] * scale];
          var size = norm(step);
          count = size > 1e-12 ? Math.floor(length / size + 1e-9) + 1 : 1;
        }
      }
    } else {
      start = mean;
      if (k > 1) {
        var second = centroid(members[1]);
        step = [second[0] - start[0], second[1] - start[1], second[2] - start[2]];
      } else {
        step = [0, 0, 0];
      }
      for (i = 0; i < g.ops.length; i++) {
        var b = amounts[g.ops[i].index];
        if (g.ops[i].op === "change_count") count = Math.max(1, k + roundHalfUp(b));
        else step = [step[0] * (1 + b), step[1] * (1 + b), step[2] * (1 + b)];
      }
    }
    var out = [];
    for (j = 0; j < count; j++) {
      var c = new Float64Array(24), dev = j < k && g.deviations ? g.deviations[j] : null;
      for (var q = 0; q < 8; q++) {
        for (var d = 0; d < 3; d++) {
          c[3 * q + d] = first[3 * q + d] - mean[d] + (start[d] + j * step[d]) + (dev ? dev[3 * q + d] : 0);
        }
      }
      out.push(c);
    }
    return out;
  }

  /* parsel_core.layout.rotation_layout. */
  function rotationLayout(g, parent, members, amounts) {
    var k = g.members.length, angle = g.angle, closed = g.closed, center = g.center.slice(), count = k, i, j;
    var topDown = g.mode === "top_down";
    if (topDown) center = weighted(g.center_weights, parent);
    var span = angle * (k - 1);
    for (i = 0; i < g.ops.length; i++) {
      var a = amounts[g.ops[i].index];
      if (g.ops[i].op === "change_count") {
        count = Math.max(1, k + roundHalfUp(a));
        if (closed) angle = (g.angle < 0 ? -1 : 1) * (2 * Math.PI / count);
        else if (topDown && count > 1) angle = span / (count - 1);
      } else {
        angle = g.angle * (1 + a);
        if (topDown && Math.abs(angle) > 1e-12) {
          var full = closed ? 2 * Math.PI : Math.abs(span);
          count = Math.max(1, Math.floor(full / Math.abs(angle) + 1e-9) + (closed ? 0 : 1));
        }
      }
    }
    var n = g.axis, first = members[0], out = [];
    for (j = 0; j < count; j++) {
      var t = j * angle, c = Math.cos(t), s = Math.sin(t), inst = new Float64Array(24);
      for (var q = 0; q < 8; q++) {
        var x = first[3 * q] - center[0], y = first[3 * q + 1] - center[1], z = first[3 * q + 2] - center[2];
        var dot = x * n[0] + y * n[1] + z * n[2];
        var cx = n[1] * z - n[2] * y, cy = n[2] * x - n[0] * z, cz = n[0] * y - n[1] * x;
        inst[3 * q] = center[0] + x * c + cx * s + dot * n[0] * (1 - c);
        inst[3 * q + 1] = center[1] + y * c + cy * s + dot * n[1] * (1 - c);
        inst[3 * q + 2] = center[2] + z * c + cz * s + dot * n[2] * (1 - c);
      }
      out.push(inst);
    }
    return out;
  }

  function det3(e) {
    return e[0] * (e[4] * e[8] - e[5] * e[7]) - e[1] * (e[3] * e[8] - e[5] * e[6]) + e[2] * (e[3] * e[7] - e[4] * e[6]);
  }

  /* The signs of the cage map's Jacobian determinant at the 8 corners and the centre of a
     hexahedron (corner k = 4u + 2v + w, 3 numbers each), as parsel_core.hexahedron's
     corner_jacobians and Hexahedron.volume give them. At corner k the derivatives are the
     three edges leaving it (taken from the low to the high end); at the centre, the mean
     edges (every edge leaves two corners, so the mean is the sum over corners / 8). A box
     gives nine equal signs; an edit that folds a corner past its neighbours flips some. */
  function orientations(c) {
    var signs = [], mean = [0, 0, 0, 0, 0, 0, 0, 0, 0], e, k, a, i, bit, d;
    for (k = 0; k < 8; k++) {
      e = [];
      for (a = 0; a < 3; a++) {
        bit = 4 >> a;
        for (i = 0; i < 3; i++) {
          d = c[3 * (k | bit) + i] - c[3 * (k & ~bit) + i];
          e.push(d);
          mean[3 * a + i] += d / 8;
        }
      }
      signs.push(Math.sign(det3(e)));
    }
    signs.push(Math.sign(det3(mean)));
    return signs;
  }

  /* +1 right-handed, -1 mirrored: the sign at the centre (0 flat). */
  function orientation(c) {
    return orientations(c)[8];
  }

  /* A lookup table keyed by part, group or parameter names: no prototype, so names such as
     "constructor", "toString" or "__proto__" are plain keys, never inherited members. */
  function table() {
    return Object.create(null);
  }

  /* A program on a shape: evaluate(values) gives corners; deform(...) moves the meshes. */
  function Model(scene, amounts, pointMaps) {
    this.scene = scene;
    this.amountFns = amounts;
    this.pointMaps = pointMaps || {};
    this.parameters = scene.parameters;
    this.rest = table();
    for (var pid in scene.rest) this.rest[pid] = Float64Array.from(scene.rest[pid]);
    this.meshes = table();
    this.replaced = table();
    for (var i = 0; i < scene.meshes.length; i++) {
      var m = scene.meshes[i];
      var uvw = decodeBase64(m.uvw, Float64Array);
      this.meshes[m.id] = {
        id: m.id, label: m.label, colour: m.colour, vertexCount: m.vertices,
        weights: trilinearWeights(uvw), index: decodeBase64(m.index, Uint32Array), closed: m.closed === true
      };
    }
    for (var g = 0; g < scene.groups.length; g++) {
      for (var j = 0; j < scene.groups[g].members.length; j++) this.replaced[scene.groups[g].members[j]] = true;
    }
  }

  Model.prototype.defaults = function () {
    var values = table();
    for (var i = 0; i < this.parameters.length; i++) values[this.parameters[i].name] = this.parameters[i].default;
    return values;
  };

  /* The values where the shape is at rest (every amount zero), which the page opens at. */
  Model.prototype.restValues = function () {
    var values = {};
    for (var i = 0; i < this.parameters.length; i++) {
      var p = this.parameters[i];
      values[p.name] = typeof p.rest === "number" ? p.rest : p.default;
    }
    return values;
  };

  Model.prototype.amounts = function (values) {
    var out = new Array(this.amountFns.length);
    for (var i = 0; i < this.amountFns.length; i++) out[i] = this.amountFns[i](values);
    return out;
  };

  /* Part ops first..last-1 on `parts`; `fresh` (optional) makes a target's array on first use;
   * `shifts` (optional, by follow index) conjugates following ops: p -> op(p - d) + d. */
  Model.prototype.runOps = function (first, last, parts, amounts, fresh, shifts) {
    var ops = this.scene.ops;
    for (var i = first; i < last; i++) {
      if (ops[i].kind !== "part") continue;
      var generated = ops[i].generated ? this.pointMaps[ops[i].index] : null;
      if (ops[i].generated && typeof generated !== "function") {
        throw new Error("op " + ops[i].index + " (" + ops[i].op + ") has no point map in program.js");
      }
      var d = shifts && typeof ops[i].follow === "number" ? shifts[ops[i].follow] : null;
      for (var t = 0; t < ops[i].targets.length; t++) {
        var target = ops[i].targets[t];
        if (fresh && !parts[target]) parts[target] = Float64Array.from(this.rest[target]);
        var c = parts[target], k;
        if (d) for (k = 0; k < 24; k++) c[k] -= d[k % 3];
        applyOp(ops[i], c, amounts[i], generated);
        if (d) for (k = 0; k < 24; k++) c[k] += d[k % 3];
      }
    }
  };

  /* How far the layers run so far moved each followed point (parsel_core.program.Follow). */
  Model.prototype.followShifts = function (first, last, parts) {
    var shifts = {}, ops = this.scene.ops, follows = this.scene.follows || [];
    for (var i = first; i < last; i++) {
      var n = ops[i].follow;
      if (typeof n !== "number" || shifts[n]) continue;
      var f = follows[n], c = parts[f.part], d = new Float64Array(3);
      for (var a = 0; a < 3; a++) {
        var s = 0;
        for (var k = 0; k < 8; k++) s += f.weights[k] * c[3 * k + a];
        d[a] = s - f.point[a];
      }
      shifts[n] = d;
    }
    return shifts;
  };

  /* {parts: {id: Float64Array(24)}, instances: {group: [Float64Array(24)]}, removed: {id: true}} */
  Model.prototype.evaluate = function (values) {
    var amounts = this.amounts(values), parts = table(), pid, i, t;
    for (pid in this.rest) parts[pid] = Float64Array.from(this.rest[pid]);
    var layers = this.scene.layers || [[0, this.scene.ops.length]];
    if (layers.length <= 1) {
      this.runOps(0, this.scene.ops.length, parts, amounts, false);
    } else {
      var outer = this.scene.outer || [];
      for (i = 0; i < layers.length; i++) {
        if (outer.indexOf(i) >= 0) continue;
        var layer = table();
        this.runOps(layers[i][0], layers[i][1], layer, amounts, true);
        for (pid in layer) {
          var total = parts[pid], moved = layer[pid], rest = this.rest[pid];
          for (t = 0; t < 24; t++) total[t] = total[t] + (moved[t] - rest[t]);
        }
      }
      for (i = 0; i < outer.length; i++) {  /* outer layers: in turn, on the sum, following ops carried */
        var span = layers[outer[i]];
        this.runOps(span[0], span[1], parts, amounts, false, this.followShifts(span[0], span[1], parts));
      }
    }
    var instances = table(), removed = table();
    for (i = 0; i < this.scene.groups.length; i++) {
      var g = this.scene.groups[i], members = [];
      for (t = 0; t < g.members.length; t++) members.push(parts[g.members[t]]);
      var laid = g.kind === "translation" ? translationLayout(g, parts[g.id], members, amounts)
        : rotationLayout(g, parts[g.id], members, amounts);
      for (t = 0; t < g.members.length; t++) {
        if (t < laid.length) {
          parts[g.members[t]] = Float64Array.from(laid[t]);
        } else {
          parts[g.members[t]] = new Float64Array(24).fill(NaN);
          removed[g.members[t]] = true;
        }
      }
      instances[g.id] = laid;
    }
    return { parts: parts, instances: instances, removed: removed, amounts: amounts };
  };

  /* Vertices (Float32Array m * 3, written into `out` when given) of a mesh in `corners`. */
  Model.prototype.deformInto = function (meshId, corners, out) {
    var mesh = this.meshes[meshId], W = mesh.weights, m = mesh.vertexCount;
    out = out || new Float32Array(m * 3);
    var c0x = corners[0], c0y = corners[1], c0z = corners[2], c1x = corners[3], c1y = corners[4], c1z = corners[5];
    var c2x = corners[6], c2y = corners[7], c2z = corners[8], c3x = corners[9], c3y = corners[10], c3z = corners[11];
    var c4x = corners[12], c4y = corners[13], c4z = corners[14], c5x = corners[15], c5y = corners[16];
    var c5z = corners[17], c6x = corners[18], c6y = corners[19], c6z = corners[20], c7x = corners[21];
    var c7y = corners[22], c7z = corners[23];
    for (var i = 0, b = 0, o = 0; i < m; i++, b += 8, o += 3) {
      var w0 = W[b], w1 = W[b + 1], w2 = W[b + 2], w3 = W[b + 3], w4 = W[b + 4], w5 = W[b + 5], w6 = W[b + 6];
      var w7 = W[b + 7];
      out[o] = w0 * c0x + w1 * c1x + w2 * c2x + w3 * c3x + w4 * c4x + w5 * c5x + w6 * c6x + w7 * c7x;
      out[o + 1] = w0 * c0y + w1 * c1y + w2 * c2y + w3 * c3y + w4 * c4y + w5 * c5y + w6 * c6y + w7 * c7y;
      out[o + 2] = w0 * c0z + w1 * c1z + w2 * c2z + w3 * c3z + w4 * c4z + w5 * c5z + w6 * c6z + w7 * c7z;
    }
    return out;
  };

  /* Whether a mesh placed in `corners` may be turned (partly) inside out relative to its rest
     hexahedron: the cage map's Jacobian at a corner or the centre has another sign than at
     rest, or vanishes. Back faces of such a mesh can show, so culling must be off for it. */
  Model.prototype.flipped = function (meshId, corners) {
    var rest = orientation(this.rest[meshId]), now = orientations(corners);
    for (var i = 0; i < now.length; i++) if (now[i] !== rest) return true;
    return false;
  };

  /* What is drawn: [{name, mesh (source part id), corners}], group members replaced by instances
     (named <first member>#<i>, as parsel_mesh.deform names them). */
  Model.prototype.drawList = function (evaluation) {
    var list = [], i, pid;
    for (i = 0; i < this.scene.meshes.length; i++) {
      pid = this.scene.meshes[i].id;
      if (!this.replaced[pid]) list.push({ name: pid, mesh: pid, corners: evaluation.parts[pid] });
    }
    for (i = 0; i < this.scene.groups.length; i++) {
      var g = this.scene.groups[i], inst = evaluation.instances[g.id] || [];
      for (var j = 0; j < inst.length; j++) list.push({ name: g.members[0] + "#" + j, mesh: g.members[0], corners: inst[j] });
    }
    return list;
  };

  /* Cube coordinates (u, v, w) of point p in hexahedron c: parsel_core.cage.inverse_trilinear
     (the affine solve, then Newton steps where the cage is not a parallelepiped). */
  function solve3(m, r) {  /* m row-major 3x3 with columns the derivatives; returns m^-1 r */
    var d = det3(m);
    if (!(Math.abs(d) > 0)) return null;
    var inv = [m[4] * m[8] - m[5] * m[7], m[2] * m[7] - m[1] * m[8], m[1] * m[5] - m[2] * m[4],
      m[5] * m[6] - m[3] * m[8], m[0] * m[8] - m[2] * m[6], m[2] * m[3] - m[0] * m[5],
      m[3] * m[7] - m[4] * m[6], m[1] * m[6] - m[0] * m[7], m[0] * m[4] - m[1] * m[3]];
    return [(inv[0] * r[0] + inv[1] * r[1] + inv[2] * r[2]) / d, (inv[3] * r[0] + inv[4] * r[1] + inv[5] * r[2]) / d,
      (inv[6] * r[0] + inv[7] * r[1] + inv[8] * r[2]) / d];
  }

  function cubeCoordinates(c, p) {
    var frame = [], a, i, k;
    for (i = 0; i < 3; i++) {
      frame.push(c[12 + i] - c[i], c[6 + i] - c[i], c[3 + i] - c[i]);  /* row i: d/du, d/dv, d/dw */
    }
    var uvw = solve3(frame, [p[0] - c[0], p[1] - c[1], p[2] - c[2]]);
    if (!uvw) return null;
    for (var it = 0; it < 30; it++) {
      var w = trilinearWeights(uvw), q = [0, 0, 0], jac = [0, 0, 0, 0, 0, 0, 0, 0, 0];
      for (k = 0; k < 8; k++) {
        var bits = [(k >> 2) & 1, (k >> 1) & 1, k & 1];
        var f = [bits[0] ? uvw[0] : 1 - uvw[0], bits[1] ? uvw[1] : 1 - uvw[1], bits[2] ? uvw[2] : 1 - uvw[2]];
        var du = (2 * bits[0] - 1) * f[1] * f[2], dv = (2 * bits[1] - 1) * f[0] * f[2], dw = (2 * bits[2] - 1) * f[0] * f[1];
        for (i = 0; i < 3; i++) {
          q[i] += w[k] * c[3 * k + i];
          jac[3 * i] += du * c[3 * k + i]; jac[3 * i + 1] += dv * c[3 * k + i]; jac[3 * i + 2] += dw * c[3 * k + i];
        }
      }
      var r = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
      if (Math.max(Math.abs(r[0]), Math.abs(r[1]), Math.abs(r[2])) < (it === 0 ? 1e-9 : 1e-13)) break;
      var step = solve3(jac, r);
      if (!step) break;
      for (a = 0; a < 3; a++) uvw[a] -= step[a];
    }
    return uvw;
  }

  /* parsel_core.report.sliding_error for one evaluation: how far `member`'s contact slid off the other part. */
  function slidingError(rel, parts, member) {
    var own = parts[member], otherId = rel.members[member === rel.members[0] ? 1 : 0], target = parts[otherId];
    if (!own || !target || own[0] !== own[0] || target[0] !== target[0]) return 0;
    var ownW = rel.weights[member === rel.members[0] ? 0 : 1], otherW = rel.weights[member === rel.members[0] ? 1 : 0];
    var extents = [0, 0, 0], axisCorner = [4, 2, 1], a, i, k, worst = 0;
    for (a = 0; a < 3; a++) {
      var e = axisCorner[a];
      extents[a] = Math.hypot(target[3 * e] - target[0], target[3 * e + 1] - target[1], target[3 * e + 2] - target[2]);
    }
    for (i = 0; i < ownW.length; i++) {
      var p = weighted(ownW[i], own), uvw = cubeCoordinates(target, p);
      if (!uvw) return Infinity;
      var restUvw = [0, 0, 0];
      for (k = 0; k < 8; k++) {
        restUvw[0] += otherW[i][k] * ((k >> 2) & 1); restUvw[1] += otherW[i][k] * ((k >> 1) & 1);
        restUvw[2] += otherW[i][k] * (k & 1);
      }
      for (a = 0; a < 3; a++) {
        var boundary = Math.abs(restUvw[a]) < 1e-9 || Math.abs(restUvw[a] - 1) < 1e-9;
        var drift = boundary ? Math.abs(uvw[a] - restUvw[a]) : Math.max(0, -uvw[a]) + Math.max(0, uvw[a] - 1);
        worst = Math.max(worst, drift * extents[a]);
      }
    }
    return worst;
  }

  /* parsel_core.report.relation_error for one evaluation (0 when a member was removed). */
  function relationError(rel, parts, rest) {
    var i, j;
    if (rel.sliding && rel.sliding.length) {
      var slid = 0;
      for (j = 0; j < rel.sliding.length; j++) slid = Math.max(slid, slidingError(rel, parts, rel.sliding[j]));
      return slid;
    }
    var residual = rel.r0.slice(), members = [];
    for (j = 0; j < rel.members.length; j++) {
      var c = parts[rel.members[j]];
      if (!c || c[0] !== c[0]) return 0;
      members.push(c);
    }
    for (i = 0; i < rel.vals.length; i++) {
      var col = rel.cols[i], m = (col / 24) | 0, k = col % 24;
      residual[rel.rows[i]] += rel.vals[i] * (members[m][k] - rest[rel.members[m]][k]);
    }
    var error = 0;
    for (i = 0; i < residual.length; i++) error = Math.max(error, Math.abs(residual[i]));
    if (error > 0 && rel.face) {
      error = Math.min(error, slidingError(rel, parts, rel.members[0]), slidingError(rel, parts, rel.members[1]));
    }
    return error;
  }

  /* The relations an evaluation breaks: [{id, kind, names, error, mayBreak}], worst first. */
  Model.prototype.brokenRelations = function (evaluation) {
    var out = [], relations = this.scene.relations || [];
    for (var i = 0; i < relations.length; i++) {
      var rel = relations[i], error = relationError(rel, evaluation.parts, this.rest);
      if (!(error < rel.allowance)) {
        out.push({ id: rel.id, kind: rel.kind, names: rel.names.slice(), error: error, mayBreak: rel.may_break === true });
      }
    }
    out.sort(function (a, b) { return b.error - a.error; });
    return out;
  };

  var api = {
    Model: Model, relationError: relationError, cubeCoordinates: cubeCoordinates, table: table, orientation: orientation, orientations: orientations, decodeBase64: decodeBase64,
    trilinearWeights: trilinearWeights, applyOp: applyOp, translationLayout: translationLayout,
    rotationLayout: rotationLayout, POINT_MAPS: POINT_MAPS
  };
  root.ParselEval = api;
  if (typeof module !== "undefined" && module.exports) module.exports = api;
})(typeof window !== "undefined" ? window : globalThis);
