/* viewer.js: the parsel slider page. One slider per program parameter; moving one
 * re-evaluates the program and deforms the meshes right here (parsel_eval.js), then
 * draws them (minigl.js). Nothing goes back to the server.
 *
 * Each slider is labelled with the request it came from (the program's metadata) and its
 * parameter name. After every step the relations are checked (parsel_eval.js): the page
 * names any the current values break, by part names, instead of showing floating parts
 * silently. The camera fits the bounds of the shape over the whole box of parameter
 * ranges (scene.view_bounds), so the shape stays in view as it grows; "reset view" returns to it.
 *
 * window.parsel is a small hook for tests and for the curious: values(), set(name, v),
 * vertices(name), corners(name), instances(group), labelAt(x, y), broken(), screenExtent(),
 * resetView(), measureFps(ms).
 */
(function () {
  "use strict";

  var state = {
    model: null, renderer: null, camera: null, values: ParselEval.table(), evaluation: null, base: null, groups: [],
    names: [null], hovered: 0, frameRequested: false, pickAt: null, updates: 0, frames: 0, sliders: ParselEval.table(),
    measuring: false, broken: [], brokenText: null
  };

  function byId(id) { return document.getElementById(id); }

  function loadScene() {
    var inline = byId("parsel-scene");
    if (inline) return Promise.resolve(JSON.parse(inline.textContent));
    return fetch("scene.json").then(function (r) {
      if (!r.ok) throw new Error("scene.json: HTTP " + r.status);
      return r.json();
    });
  }

  function format(value) {
    return Math.abs(value) >= 1000 || (value !== 0 && Math.abs(value) < 1e-3) ? value.toExponential(3) : value.toFixed(3);
  }

  function showValues() {
    var parts = [];
    for (var name in state.values) {
      parts.push(name + " = " + format(state.values[name]));
      if (state.sliders[name]) state.sliders[name].output.textContent = format(state.values[name]);
    }
    byId("values").textContent = parts.join(", ");
  }

  function sameCorners(a, b) {
    if (!a || !b) return false;
    for (var i = 0; i < 24; i++) if (a[i] !== b[i] && !(a[i] !== a[i] && b[i] !== b[i])) return false;
    return true;
  }

  /* A new pick id for a drawn thing (a part, or one instance of a group). */
  function newId(name, label) {
    state.names.push({ name: name, label: label });
    return state.names.length - 1;
  }

  /* Copies of meshes in one vertex buffer: slots[i] = {mesh, first vertex, vertex count, id}. */
  function buildBatch(slots) {
    var model = state.model, vertices = 0, indices = 0, closed = true, i;
    for (i = 0; i < slots.length; i++) {
      var source = model.meshes[slots[i].mesh];
      closed = closed && source.closed;
      slots[i].first = vertices;
      slots[i].count = source.vertexCount;
      vertices += source.vertexCount;
      indices += source.index.length;
    }
    var positions = new Float32Array(vertices * 3), colours = new Float32Array(vertices * 3);
    var ids = new Float32Array(vertices), index = new Uint32Array(indices), at = 0;
    for (i = 0; i < slots.length; i++) {
      var slot = slots[i], mesh = model.meshes[slot.mesh];
      for (var v = slot.first; v < slot.first + slot.count; v++) {
        colours[3 * v] = mesh.colour[0]; colours[3 * v + 1] = mesh.colour[1]; colours[3 * v + 2] = mesh.colour[2];
        ids[v] = slot.id;
      }
      for (var f = 0; f < mesh.index.length; f++) index[at + f] = mesh.index[f] + slot.first;
      at += mesh.index.length;
      slot.corners = null;
    }
    return { batch: state.renderer.addBatch(positions, index, colours, ids), positions: positions, slots: slots,
      closed: closed };
  }

  function buildScene() {
    var model = state.model, slots = [];
    for (var i = 0; i < model.scene.meshes.length; i++) {
      var m = model.scene.meshes[i];
      if (!model.replaced[m.id]) slots.push({ name: m.id, mesh: m.id, id: newId(m.id, m.label) });
    }
    state.base = buildBatch(slots);
    state.base.byName = ParselEval.table();
    slots.forEach(function (s) { state.base.byName[s.name] = s; });
    state.groups = model.scene.groups.map(function (g) {
      return { id: g.id, member: g.members[0], label: model.meshes[g.members[0]].label, ids: [], drawn: null, shown: 0 };
    });
  }

  /* Make room for `count` instances of a group: rebuild its batch with twice the capacity. */
  function groupBatch(group, count) {
    if (group.drawn && group.drawn.slots.length >= count) return group.drawn;
    var capacity = Math.max(count, group.drawn ? 2 * group.drawn.slots.length : 8), slots = [];
    while (group.ids.length < capacity) group.ids.push(newId(group.member + "#" + group.ids.length, group.label));
    for (var j = 0; j < capacity; j++) slots.push({ name: group.member + "#" + j, mesh: group.member, id: group.ids[j] });
    if (group.drawn) state.renderer.removeBatch(group.drawn.batch);
    group.drawn = buildBatch(slots);
    return group.drawn;
  }

  function place(drawn, slot, corners) {
    if (sameCorners(slot.corners, corners)) return;
    state.model.deformInto(slot.mesh, corners, drawn.positions.subarray(3 * slot.first, 3 * (slot.first + slot.count)));
    state.renderer.setPositions(drawn.batch, drawn.positions, slot.first, slot.count);
    slot.corners = Float64Array.from(corners);
    slot.flipped = state.model.flipped(slot.mesh, corners);
  }

  /* Back faces of closed meshes are never seen, so the renderer may skip them (half the
     triangles: what limits a software rasteriser), unless a shown copy is mirrored or folded. */
  function setCulling(drawn, shown) {
    var cull = drawn.closed;
    for (var i = 0; i < shown && cull; i++) cull = !drawn.slots[i].flipped;
    drawn.batch.cull = cull;
  }

  /* Say which relations the current values break (by part names), or that all hold. */
  function showRelations(evaluation) {
    var box = byId("relations"), broken = state.model.brokenRelations(evaluation);
    state.broken = broken;
    var unexpected = broken.filter(function (b) { return !b.mayBreak; });
    var text = broken.map(function (b) { return b.id + (b.mayBreak ? "*" : ""); }).join(",");
    if (text === state.brokenText) return;
    state.brokenText = text;
    var total = (state.model.scene.relations || []).length;
    box.textContent = "";
    if (!broken.length) {
      box.className = "";
      box.textContent = "all " + total + " relations hold";
      return;
    }
    box.className = unexpected.length ? "broken" : "";
    box.appendChild(document.createTextNode(unexpected.length
      ? unexpected.length + " relation" + (unexpected.length > 1 ? "s" : "") + " broken at these values:"
      : "only relations the request allows to break are broken:"));
    var list = document.createElement("ul");
    broken.slice(0, 8).forEach(function (b) {
      var item = document.createElement("li");
      item.textContent = b.names.join(" \u2013 ") + " (" + b.kind + " " + b.id + (b.mayBreak ? ", allowed" : "") + ")";
      list.appendChild(item);
    });
    if (broken.length > 8) {
      var more = document.createElement("li");
      more.textContent = "and " + (broken.length - 8) + " more";
      list.appendChild(more);
    }
    box.appendChild(list);
  }

  /* One slider step: evaluate the program, move the meshes whose corners changed. */
  function update() {
    var evaluation = state.model.evaluate(state.values), i, j;
    var slots = state.base.slots;
    for (i = 0; i < slots.length; i++) place(state.base, slots[i], evaluation.parts[slots[i].name]);
    setCulling(state.base, slots.length);
    for (i = 0; i < state.groups.length; i++) {
      var group = state.groups[i], instances = evaluation.instances[group.id] || [];
      var drawn = groupBatch(group, instances.length);
      for (j = 0; j < instances.length; j++) place(drawn, drawn.slots[j], instances[j]);
      setCulling(drawn, instances.length);
      var perInstance = state.model.meshes[group.member].index.length;
      drawn.batch.count = instances.length * perInstance;
      group.shown = instances.length;
    }
    state.evaluation = evaluation;
    state.updates++;
    showValues();
    showRelations(evaluation);
    requestFrame();
  }

  function draw() {
    state.frameRequested = false;
    if (state.pickAt) {
      showTooltip(state.renderer.pick(state.camera, state.pickAt[0], state.pickAt[1]), state.pickAt);
      state.pickAt = null;
    }
    state.renderer.draw(state.camera, state.hovered);
    state.frames++;
  }

  function requestFrame() {
    if (state.frameRequested || state.measuring) return;
    state.frameRequested = true;
    requestAnimationFrame(draw);
  }

  function showTooltip(id, at) {
    var tip = byId("tooltip"), entry = id ? state.names[id] : null;
    state.hovered = entry ? id : 0;
    if (!entry) { tip.hidden = true; return; }
    tip.textContent = entry.label + " (" + entry.name + ")";
    tip.style.left = (at[0] + 14) + "px";
    tip.style.top = (at[1] + 10) + "px";
    tip.hidden = false;
  }

  /* Where the vertices of a drawn part or instance are: [batch, slot], or null. */
  function findSlot(name) {
    if (state.base.byName[name]) return [state.base, state.base.byName[name]];
    for (var i = 0; i < state.groups.length; i++) {
      var g = state.groups[i];
      if (g.drawn && name.indexOf(g.member + "#") === 0) {
        var j = parseInt(name.slice(g.member.length + 1), 10);
        if (j >= 0 && j < g.shown) return [g.drawn, g.drawn.slots[j]];
      }
    }
    return null;
  }

  function buildSliders(parameters, requests) {
    var box = byId("sliders");
    parameters.forEach(function (p) {
      var row = document.createElement("div");
      row.className = "slider";
      var request = null;
      if (requests && typeof requests[p.name] === "string" && requests[p.name]) {
        request = document.createElement("div");
        request.className = "request";
        request.id = "request-" + p.name;
        request.textContent = requests[p.name];
      }
      var label = document.createElement("label");
      label.textContent = p.name;
      var input = document.createElement("input");
      input.type = "range";
      input.min = String(p.lo);
      input.max = String(p.hi);
      input.step = "any";  // typed and dragged values are kept exactly; keys move 1% (below)
      input.value = String(state.values[p.name]);
      input.id = "slider-" + p.name;
      input.setAttribute("aria-label", request ? p.name + ": " + request.textContent : p.name);
      input.dataset.parameter = p.name;
      label.htmlFor = input.id;
      var output = document.createElement("output");
      output.htmlFor = input.id;
      var range = document.createElement("span");
      range.className = "range";
      range.textContent = "[" + format(p.lo) + ", " + format(p.hi) + "]";
      input.addEventListener("input", function () {
        state.values[p.name] = parseFloat(input.value);
        update();
      });
      input.addEventListener("keydown", function (e) {
        // Arrow keys move 1% of the range, Page Up / Down 10%, Home / End to the ends.
        var span = p.hi - p.lo, value = parseFloat(input.value), steps = {
          ArrowRight: 0.01, ArrowUp: 0.01, ArrowLeft: -0.01, ArrowDown: -0.01, PageUp: 0.1, PageDown: -0.1
        };
        if (e.key in steps) value += steps[e.key] * span;
        else if (e.key === "Home") value = p.lo;
        else if (e.key === "End") value = p.hi;
        else return;
        e.preventDefault();
        if (!(span > 0)) return;
        value = Math.min(p.hi, Math.max(p.lo, Math.round((value - p.lo) / span * 100) / 100 * span + p.lo));
        input.value = String(value);
        state.values[p.name] = value;
        update();
      });
      if (request) row.appendChild(request);
      row.appendChild(label); row.appendChild(input); row.appendChild(output); row.appendChild(range);
      box.appendChild(row);
      state.sliders[p.name] = { input: input, output: output, parameter: p };
    });
  }

  function installControls(canvas) {
    var drag = null;
    canvas.addEventListener("pointerdown", function (e) {
      drag = { x: e.clientX, y: e.clientY, yaw: state.camera.yaw, pitch: state.camera.pitch };
      canvas.setPointerCapture(e.pointerId);
    });
    canvas.addEventListener("pointerup", function (e) { drag = null; canvas.releasePointerCapture(e.pointerId); });
    canvas.addEventListener("pointermove", function (e) {
      var rect = canvas.getBoundingClientRect();
      if (drag) {
        state.camera.yaw = drag.yaw - (e.clientX - drag.x) * 0.01;
        state.camera.pitch = Math.max(-1.5, Math.min(1.5, drag.pitch + (e.clientY - drag.y) * 0.01));
      }
      state.pickAt = [e.clientX - rect.left, e.clientY - rect.top];
      requestFrame();
    });
    canvas.addEventListener("pointerleave", function () { showTooltip(0); requestFrame(); });
    canvas.addEventListener("wheel", function (e) {
      e.preventDefault();
      state.camera.distance *= Math.exp(e.deltaY * 0.001);
      requestFrame();
    }, { passive: false });
    window.addEventListener("resize", requestFrame);
    byId("reset-view").addEventListener("click", function () { resetView(); requestFrame(); });
  }

  /* The camera that shows the shape's bounds over the whole parameter box: centred on them,
     far enough that their bounding sphere fits the narrower field of view of the canvas. */
  function resetView() {
    var b = state.model.scene.view_bounds || state.model.scene.bounds, lo = b[0], hi = b[1];
    var centre = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2];
    var radius = Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2 || 0.5;
    var canvas = state.renderer.canvas, aspect = (canvas.clientWidth || 1) / (canvas.clientHeight || 1);
    var half = Math.min(0.35, Math.atan(Math.tan(0.35) * aspect));  // the camera's vertical fov is 0.7
    var distance = radius / Math.sin(half) * 1.08;
    if (!state.camera) state.camera = new MiniGL.OrbitCamera(centre, distance);
    state.camera.target = centre;
    state.camera.distance = distance;
    state.camera.yaw = -0.75;
    state.camera.pitch = 0.35;
  }

  /* Where the drawn vertices land on the canvas: [min x, max x, min y, max y] in clip space
     (the canvas spans -1..1 both ways). */
  function screenExtent() {
    var canvas = state.renderer.canvas, aspect = (canvas.clientWidth || 1) / (canvas.clientHeight || 1);
    var m = state.camera.matrix(aspect), out = [Infinity, -Infinity, Infinity, -Infinity];
    function visit(drawn, count) {
      for (var s = 0; s < count; s++) {
        var slot = drawn.slots[s], pos = drawn.positions;
        for (var v = slot.first; v < slot.first + slot.count; v++) {
          var x = pos[3 * v], y = pos[3 * v + 1], z = pos[3 * v + 2];
          var w = m[3] * x + m[7] * y + m[11] * z + m[15];
          var px = (m[0] * x + m[4] * y + m[8] * z + m[12]) / w, py = (m[1] * x + m[5] * y + m[9] * z + m[13]) / w;
          out[0] = Math.min(out[0], px); out[1] = Math.max(out[1], px);
          out[2] = Math.min(out[2], py); out[3] = Math.max(out[3], py);
        }
      }
    }
    visit(state.base, state.base.slots.length);
    state.groups.forEach(function (g) { if (g.drawn) visit(g.drawn, g.shown); });
    return out;
  }

  /* Sweep the first slider for `ms` milliseconds, one slider step and one frame per animation
     frame, and report the frame rate and the time each frame's work took (GPU included:
     one pixel is read back, which waits for the frame to finish). */
  function measureFps(ms, sync) {
    sync = sync !== false;
    var p = state.model.parameters[0], input = state.sliders[p.name].input;
    state.measuring = true;
    return new Promise(function (resolve) {
      var start = null, last = null, intervals = [], work = [], frames = 0, gl = state.renderer.gl;
      var pixel = new Uint8Array(4);
      function frame(now) {
        if (start === null) { start = now; last = now; requestAnimationFrame(frame); return; }
        intervals.push(now - last);
        last = now;
        var t0 = performance.now(), phase = ((now - start) / 1000) % 2;
        var value = p.lo + (p.hi - p.lo) * (phase < 1 ? phase : 2 - phase);
        input.value = String(value);
        state.values[p.name] = parseFloat(input.value);
        update();
        state.renderer.draw(state.camera, null);
        if (sync) gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
        work.push(performance.now() - t0);
        frames++;
        if (now - start < ms) { requestAnimationFrame(frame); return; }
        state.measuring = false;
        var sorted = work.slice().sort(function (a, b) { return a - b; });
        var sortedIntervals = intervals.slice().sort(function (a, b) { return a - b; });
        resolve({
          frames: frames, seconds: (now - start) / 1000, fps: frames / ((now - start) / 1000),
          medianIntervalMs: sortedIntervals[Math.floor(sortedIntervals.length / 2)],
          meanWorkMs: work.reduce(function (a, b) { return a + b; }, 0) / work.length,
          p95WorkMs: sorted[Math.min(sorted.length - 1, Math.floor(sorted.length * 0.95))],
          maxWorkMs: sorted[sorted.length - 1]
        });
        requestFrame();
      }
      requestAnimationFrame(frame);
    });
  }

  function hook() {
    return {
      ready: true,
      parameters: function () { return state.model.parameters; },
      values: function () { return Object.assign(ParselEval.table(), state.values); },
      set: function (name, value) {
        var slider = state.sliders[name];
        if (!slider) throw new Error("no parameter " + name);
        slider.input.value = String(value);
        slider.input.dispatchEvent(new Event("input", { bubbles: true }));
        return state.values[name];
      },
      names: function () {
        var out = state.base.slots.map(function (s) { return s.name; });
        state.groups.forEach(function (g) { for (var j = 0; j < g.shown; j++) out.push(g.member + "#" + j); });
        return out;
      },
      vertices: function (name) {
        var found = findSlot(name);
        if (!found) throw new Error("nothing named " + name + " is drawn");
        var slot = found[1];
        return Array.from(found[0].positions.subarray(3 * slot.first, 3 * (slot.first + slot.count)));
      },
      corners: function (name) {
        var c = state.evaluation.parts[name];
        if (!c) throw new Error("no part " + name);
        return Array.from(c);
      },
      instances: function (group) {
        return (state.evaluation.instances[group] || []).map(function (c) { return Array.from(c); });
      },
      labelAt: function (x, y) {
        var id = state.renderer.pick(state.camera, x, y);
        return id ? Object.assign({}, state.names[id]) : null;
      },
      drawNow: function () { state.renderer.draw(state.camera, state.hovered); },
      broken: function () { return state.broken.map(function (b) { return Object.assign({}, b); }); },
      screenExtent: screenExtent,
      resetView: function () { resetView(); requestFrame(); },
      updates: function () { return state.updates; },
      frames: function () { return state.frames; },
      measureFps: measureFps
    };
  }

  function start(scene) {
    var model = new ParselEval.Model(scene, window.PARSEL_AMOUNTS || [], window.PARSEL_POINT_MAPS || {});
    state.model = model;
    state.values = model.restValues();
    document.title = "parsel: " + scene.title;
    byId("title").textContent = scene.title;
    var meta = scene.metadata || {};
    byId("request").textContent = meta.request || meta.seed || "";
    byId("program").textContent = scene.program_text;
    var canvas = byId("view");
    state.renderer = new MiniGL.Renderer(canvas);
    resetView();
    buildScene();
    buildSliders(model.parameters, scene.sliders);
    installControls(canvas);
    update();
    window.parsel = hook();
    byId("status").textContent = scene.meshes.length + " parts, " +
      scene.meshes.reduce(function (n, m) { return n + m.vertices; }, 0) + " vertices";
  }

  function fail(error) {
    byId("status").textContent = "error: " + (error && error.message ? error.message : error);
    byId("status").className = "error";
    window.parsel = { ready: false, error: String(error && error.message ? error.message : error) };
  }

  function boot() {
    loadScene().then(start).catch(fail);
  }

  if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", boot);
  else boot();
})();
