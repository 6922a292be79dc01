/* minigl.js: the small WebGL2 renderer of the parsel slider page (MIT, part of parsel-view).
 *
 * Just what the page needs, so the package carries ~10 KB instead of a general 3D
 * library: batches of indexed triangle meshes (one draw call each) with a colour and an
 * id per vertex, flat shading from screen-space derivatives (deformed meshes need no
 * normal recomputation), an orbit camera, and picking by drawing the ids into an
 * offscreen buffer and reading one pixel.
 */
(function (root) {
  "use strict";

  var VERTEX = "#version 300 es\n" +
    "in vec3 position; in vec3 colour; in float id;\n" +
    "uniform mat4 viewProjection;\n" +
    "out vec3 world; out vec3 vColour; flat out float vId;\n" +
    "void main() { world = position; vColour = colour; vId = id; gl_Position = viewProjection * vec4(position, 1.0); }\n";

  var FRAGMENT = "#version 300 es\nprecision highp float;\n" +
    "in vec3 world; in vec3 vColour; flat in float vId;\n" +
    "uniform vec3 eye; uniform float hovered; uniform int pickMode;\n" +
    "out vec4 fragment;\n" +
    "const vec3 KEY = vec3(0.34, 0.77, 0.51); const vec3 FILL = vec3(-0.77, 0.38, -0.51);\n" +
    "void main() {\n" +
    "  if (pickMode == 1) {\n" +
    "    fragment = vec4(mod(vId, 256.0), mod(floor(vId / 256.0), 256.0), floor(vId / 65536.0), 255.0) / 255.0;\n" +
    "    return;\n" +
    "  }\n" +
    "  vec3 n = normalize(cross(dFdx(world), dFdy(world)));\n" +
    "  n *= sign(dot(n, eye - world));\n" +
    "  float light = 0.38 + 0.55 * max(dot(n, KEY), 0.0) + 0.2 * max(dot(n, FILL), 0.0);\n" +
    "  float glow = abs(vId - hovered) < 0.5 ? 1.0 : 0.0;\n" +
    "  fragment = vec4(min(vColour * light + glow * vec3(0.25, 0.22, 0.1), 1.0), 1.0);\n" +
    "}\n";

  function compile(gl, type, source) {
    var shader = gl.createShader(type);
    gl.shaderSource(shader, source);
    gl.compileShader(shader);
    if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
    return shader;
  }

  /* 4x4 matrices, column-major as WebGL wants them. */
  function perspective(fovy, aspect, near, far) {
    var f = 1 / Math.tan(fovy / 2), nf = 1 / (near - far);
    return [f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0];
  }

  function lookAt(eye, target, up) {
    var z = [eye[0] - target[0], eye[1] - target[1], eye[2] - target[2]];
    var lz = Math.hypot(z[0], z[1], z[2]); z = [z[0] / lz, z[1] / lz, z[2] / lz];
    var x = [up[1] * z[2] - up[2] * z[1], up[2] * z[0] - up[0] * z[2], up[0] * z[1] - up[1] * z[0]];
    var lx = Math.hypot(x[0], x[1], x[2]); x = [x[0] / lx, x[1] / lx, x[2] / lx];
    var y = [z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]];
    return [x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0,
      -(x[0] * eye[0] + x[1] * eye[1] + x[2] * eye[2]), -(y[0] * eye[0] + y[1] * eye[1] + y[2] * eye[2]),
      -(z[0] * eye[0] + z[1] * eye[1] + z[2] * eye[2]), 1];
  }

  function multiply(a, b) {
    var out = new Array(16);
    for (var c = 0; c < 4; c++) {
      for (var r = 0; r < 4; r++) {
        out[4 * c + r] = a[r] * b[4 * c] + a[4 + r] * b[4 * c + 1] + a[8 + r] * b[4 * c + 2] + a[12 + r] * b[4 * c + 3];
      }
    }
    return out;
  }

  /* An orbit camera about `target`: yaw / pitch in radians, distance in scene units. */
  function OrbitCamera(target, distance) {
    this.target = target.slice();
    this.distance = distance;
    this.yaw = -0.75;
    this.pitch = 0.35;
  }

  OrbitCamera.prototype.eye = function () {
    var cp = Math.cos(this.pitch);
    return [this.target[0] + this.distance * cp * Math.sin(this.yaw),
      this.target[1] + this.distance * Math.sin(this.pitch),
      this.target[2] + this.distance * cp * Math.cos(this.yaw)];
  };

  OrbitCamera.prototype.matrix = function (aspect) {
    return multiply(perspective(0.7, aspect, this.distance * 0.02, this.distance * 20),
      lookAt(this.eye(), this.target, [0, 1, 0]));
  };

  function Renderer(canvas) {
    var gl = canvas.getContext("webgl2", { antialias: false, preserveDrawingBuffer: false, powerPreference: "high-performance" });
    if (!gl) throw new Error("this browser has no WebGL2");
    this.gl = gl;
    this.canvas = canvas;
    this.meshes = [];
    var program = gl.createProgram();
    gl.attachShader(program, compile(gl, gl.VERTEX_SHADER, VERTEX));
    gl.attachShader(program, compile(gl, gl.FRAGMENT_SHADER, FRAGMENT));
    gl.linkProgram(program);
    if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
    this.program = program;
    this.loc = {
      position: gl.getAttribLocation(program, "position"),
      colour: gl.getAttribLocation(program, "colour"),
      id: gl.getAttribLocation(program, "id"),
      viewProjection: gl.getUniformLocation(program, "viewProjection"),
      eye: gl.getUniformLocation(program, "eye"),
      hovered: gl.getUniformLocation(program, "hovered"),
      pickMode: gl.getUniformLocation(program, "pickMode")
    };
    this.pickTarget = null;
    gl.enable(gl.DEPTH_TEST);
  }

  function attribute(gl, location, data, size, usage) {
    var buffer = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
    gl.bufferData(gl.ARRAY_BUFFER, data, usage);
    gl.enableVertexAttribArray(location);
    gl.vertexAttribPointer(location, size, gl.FLOAT, false, 0, 0);
    return buffer;
  }

  /* A batch: many meshes in one vertex buffer, drawn with one call (software GL pays per
     draw call, so the page draws all parts at once). positions: Float32Array (n * 3),
     updated in ranges with setPositions; colours (n * 3) and ids (n) are per vertex; an id
     identifies a mesh for picking and highlighting. `count` indices are drawn; `cull` skips
     back faces (counter-clockwise triangles face the viewer). */
  Renderer.prototype.addBatch = function (positions, index, colours, ids) {
    var gl = this.gl, batch = { count: index.length, visible: true, cull: false, vertices: positions.length / 3 };
    batch.vao = gl.createVertexArray();
    gl.bindVertexArray(batch.vao);
    batch.positions = attribute(gl, this.loc.position, positions, 3, gl.DYNAMIC_DRAW);
    batch.colours = attribute(gl, this.loc.colour, colours, 3, gl.STATIC_DRAW);
    batch.ids = attribute(gl, this.loc.id, ids, 1, gl.STATIC_DRAW);
    batch.index = gl.createBuffer();
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, batch.index);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, index, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    this.meshes.push(batch);
    return batch;
  };

  Renderer.prototype.removeBatch = function (batch) {
    var gl = this.gl, i = this.meshes.indexOf(batch);
    if (i >= 0) this.meshes.splice(i, 1);
    gl.deleteBuffer(batch.positions); gl.deleteBuffer(batch.colours); gl.deleteBuffer(batch.ids);
    gl.deleteBuffer(batch.index); gl.deleteVertexArray(batch.vao);
  };

  /* Upload positions[first * 3 .. (first + n) * 3) (all of them when first / n are omitted). */
  Renderer.prototype.setPositions = function (batch, positions, first, n) {
    var gl = this.gl;
    gl.bindBuffer(gl.ARRAY_BUFFER, batch.positions);
    if (first === undefined) gl.bufferSubData(gl.ARRAY_BUFFER, 0, positions);
    else gl.bufferSubData(gl.ARRAY_BUFFER, first * 12, positions, first * 3, n * 3);
  };

  Renderer.prototype.resize = function () {
    var ratio = (typeof devicePixelRatio === "number" ? devicePixelRatio : 1);
    var w = Math.max(1, Math.round(this.canvas.clientWidth * ratio));
    var h = Math.max(1, Math.round(this.canvas.clientHeight * ratio));
    if (this.canvas.width !== w || this.canvas.height !== h) { this.canvas.width = w; this.canvas.height = h; }
  };

  Renderer.prototype._drawAll = function (camera, pick, hovered) {
    var gl = this.gl, loc = this.loc;
    gl.useProgram(this.program);
    gl.uniformMatrix4fv(loc.viewProjection, false, camera.matrix(this.canvas.width / this.canvas.height));
    gl.uniform3fv(loc.eye, camera.eye());
    gl.uniform1i(loc.pickMode, pick ? 1 : 0);
    gl.uniform1f(loc.hovered, hovered || -1);
    for (var i = 0; i < this.meshes.length; i++) {
      var batch = this.meshes[i];
      if (!batch.visible || batch.count === 0) continue;
      if (batch.cull) gl.enable(gl.CULL_FACE); else gl.disable(gl.CULL_FACE);
      gl.bindVertexArray(batch.vao);
      gl.drawElements(gl.TRIANGLES, batch.count, gl.UNSIGNED_INT, 0);
    }
    gl.bindVertexArray(null);
  };

  /* Draw every visible batch; vertices whose id equals `hovered` are lit up. */
  Renderer.prototype.draw = function (camera, hovered) {
    var gl = this.gl;
    this.resize();
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, this.canvas.width, this.canvas.height);
    gl.clearColor(0.97, 0.97, 0.96, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    this._drawAll(camera, false, hovered);
  };

  /* The id drawn at canvas pixel (x, y) in CSS pixels (0: background). */
  Renderer.prototype.pick = function (camera, x, y) {
    var gl = this.gl, w = this.canvas.width, h = this.canvas.height;
    var ratio = w / Math.max(1, this.canvas.clientWidth);
    if (!this.pickTarget || this.pickTarget.w !== w || this.pickTarget.h !== h) {
      var fb = gl.createFramebuffer(), colour = gl.createRenderbuffer(), depth = gl.createRenderbuffer();
      gl.bindRenderbuffer(gl.RENDERBUFFER, colour);
      gl.renderbufferStorage(gl.RENDERBUFFER, gl.RGBA8, w, h);
      gl.bindRenderbuffer(gl.RENDERBUFFER, depth);
      gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT24, w, h);
      gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
      gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.RENDERBUFFER, colour);
      gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, depth);
      this.pickTarget = { fb: fb, w: w, h: h };
    }
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.pickTarget.fb);
    gl.viewport(0, 0, w, h);
    gl.clearColor(0, 0, 0, 0);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    this._drawAll(camera, true, null);
    var pixel = new Uint8Array(4);
    gl.readPixels(Math.floor(x * ratio), Math.floor(h - 1 - y * ratio), 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    return pixel[0] + (pixel[1] << 8) + (pixel[2] << 16);
  };

  root.MiniGL = { Renderer: Renderer, OrbitCamera: OrbitCamera, multiply: multiply, perspective: perspective, lookAt: lookAt };
})(typeof window !== "undefined" ? window : globalThis);
