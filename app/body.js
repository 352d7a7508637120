// The rigid body in 3-D (issue 23, item 3): plain JavaScript, no library, nothing fetched. Joined in front of
// app/ui.js into the page's one ES module (app/ui.py), which calls createBodyView.
//
// What it draws, from a series the server computed once (app/bodyview.py: explorer_core.analyses.body):
// the body as the uniform box with its principal moments (faces tinted by the principal axis they are normal
// to), its principal axes 1, 2, 3 (moments ascending) from the box to the unit sphere, the angular velocity
// omega in the space frame (arrow), the unit sphere (light wireframe; the space frame's z axis vertical) and
// the trace on it of one principal axis up to the frame shown. Orthographic projection of the space frame,
// turned by dragging. Animated with requestAnimationFrame between the recorded frames (quaternions slerped,
// omega interpolated linearly) at a speed in periods per second: no message to the server per frame.
// window.bilimovichBody is a small hook for tests and for a teacher's console (frame, fps, quaternion(i), ...).

const BODY_CSS = `
.body-view { display: flex; flex-direction: column; min-height: 0; min-width: 0; flex: 1 1 auto; gap: 3px; }
.body-view[hidden] { display: none; }
.body-view .body-canvas-box { flex: 1 1 0; min-height: 140px; position: relative; }
.body-view canvas { position: absolute; inset: 0; width: 100%; height: 100%; cursor: grab; touch-action: none;
  background: #fff; border: 1px solid #e1e5eb; border-radius: 4px; }
.body-view canvas:active { cursor: grabbing; }
.body-view .body-bar, .body-view .body-status { flex: none; }
.body-view .body-bar { display: flex; flex-wrap: wrap; gap: 6px; align-items: center; font-size: .92em; }
.body-view .body-bar button { font: inherit; padding: 2px 9px; border-radius: 4px; border: 1px solid #2c5f8a;
  background: #fff; color: #2c5f8a; cursor: pointer; }
.body-view .body-bar button.body-play { background: #2c5f8a; color: #fff; min-width: 4.2em; }
.body-view .body-bar button:disabled { opacity: .45; cursor: not-allowed; }
.body-view .body-bar select { font: inherit; padding: 1px; }
.app.present .body-view .body-bar, .app.present .body-view .body-status { font-size: .8em; }
/* One line in presentation mode (the whole text in its tooltip): the view fits 1280x720; a tall screen has room. */
.app.present .body-view .body-status { white-space: nowrap; overflow: hidden; text-overflow: ellipsis; }
@media (min-height: 900px) { .app.present .body-view .body-status { white-space: normal; } }
.body-view .body-status { font-size: .9em; color: #3a4554; min-height: 1.2em; }
.body-view .body-status.lost { color: #842029; }
`

//: Principal axes 1, 2, 3 (moments ascending) and omega: colours used on the canvas and in the legend.
const AXIS_COLOURS = ["#d62728", "#2ca02c", "#1f77b4"]
const OMEGA_COLOUR = "#111111"
//: Periods per second offered (app/state.py's BODY_SPEEDS: the state holds the one in use, the URL carries it).
const SPEEDS = [0.05, 0.1, 0.25, 0.5, 1, 2, 4]
const DEFAULT_SPEED = 0.25
//: The inertia ellipsoid's largest semi-axis (the unit sphere's radius is 1; the box's largest side is 1).
const ELLIPSOID_SIZE = 0.62

function b64Floats(text) {
  // Little-endian float32, as app/bodyview.py writes them (every browser the app supports is little-endian).
  const bin = atob(text || "")
  const bytes = new Uint8Array(bin.length)
  for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i)
  return new Float32Array(bytes.buffer, 0, bytes.length >> 2)
}

// --- small 3-D algebra (row-major 3x3 matrices as arrays of 9) ---------------------------------------------

function quatMatrix(w, x, y, z) {
  // The rotation of a unit quaternion (w, x, y, z): body -> space (normalised here: float32 rounding).
  const n = Math.hypot(w, x, y, z) || 1
  w /= n; x /= n; y /= n; z /= n
  return [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
          2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
          2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]
}

function slerp(a, b, f) {
  // Between two unit quaternions along the shorter arc (q and -q are the same rotation).
  let [aw, ax, ay, az] = a
  let [bw, bx, by, bz] = b
  let d = aw * bw + ax * bx + ay * by + az * bz
  if (d < 0) { bw = -bw; bx = -bx; by = -by; bz = -bz; d = -d }
  let s0 = 1 - f, s1 = f
  if (d < 0.9995) {
    const th = Math.acos(Math.min(1, d)), sn = Math.sin(th)
    s0 = Math.sin((1 - f) * th) / sn
    s1 = Math.sin(f * th) / sn
  }
  return [s0 * aw + s1 * bw, s0 * ax + s1 * bx, s0 * ay + s1 * by, s0 * az + s1 * bz]
}

const mv = (m, v) => [m[0] * v[0] + m[1] * v[1] + m[2] * v[2], m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
                      m[6] * v[0] + m[7] * v[1] + m[8] * v[2]]
const mm = (a, b) => {
  const o = new Array(9)
  for (let i = 0; i < 3; i++) for (let j = 0; j < 3; j++) {
    o[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j]
  }
  return o
}

function viewMatrix(yaw, pitch) {
  // Space -> view: turn about the space z axis (yaw), then tilt about the screen's horizontal axis (pitch > 0:
  // seen from above). View coordinates: x right, y away from the viewer (depth), z up.
  const cy = Math.cos(yaw), sy = Math.sin(yaw), cp = Math.cos(pitch), sp = Math.sin(pitch)
  const rz = [cy, -sy, 0, sy, cy, 0, 0, 0, 1]
  const rx = [1, 0, 0, 0, cp, -sp, 0, sp, cp]
  return mm(rx, rz)
}

function fmtNum(v, digits = 4) {
  if (!Number.isFinite(v)) return String(v)
  const a = Math.abs(v)
  return a !== 0 && (a >= 1e5 || a < 1e-3) ? v.toExponential(2) : String(+v.toFixed(Math.max(0, digits - Math.max(0, Math.floor(Math.log10(a || 1)) + 1))))
}

// --- the view --------------------------------------------------------------------------------------------

function createBodyView(host, {onPoint = null, onFrame = null, onSetting = null} = {}) {
  // onSetting(name, value): a setting chosen in the bar (body_speed, body_axis, body_shape) goes to the server,
  // which answers with the value in use (setSetting); without it (a page of its own) it applies at once.
  const mk = (tag, attrs = {}, text = null) => {
    const e = document.createElement(tag)
    for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v)
    if (text !== null) e.textContent = text
    return e
  }
  const root = mk("div", {class: "body-view", role: "region", "aria-label": "The body in 3-D"})
  const canvasBox = mk("div", {class: "body-canvas-box"})
  const canvas = mk("canvas", {class: "body-canvas", role: "img",
                               "aria-label": "The rigid body, its principal axes, omega and the unit sphere",
                               title: "Drag to turn the view"})
  canvasBox.append(canvas)
  const playBtn = mk("button", {class: "body-play", title: "Play or pause the body's motion"}, "Play")
  const backBtn = mk("button", {class: "body-step-back", title: "One recorded frame back"}, "◀")
  const stepBtn = mk("button", {class: "body-step", title: "One recorded frame on"}, "▶|")
  const speedSel = mk("select", {class: "body-speed", "aria-label": "Speed in periods per second"})
  for (const s of SPEEDS) speedSel.append(mk("option", {value: String(s)}, `${s} periods/s`))
  speedSel.value = String(DEFAULT_SPEED)
  const axisSel = mk("select", {class: "body-trace-axis", "aria-label": "Principal axis traced on the sphere"})
  for (const [i, t] of ["axis 1 (smallest moment)", "axis 2", "axis 3 (largest moment)"].entries()) {
    axisSel.append(mk("option", {value: String(i), title: `the trace of principal ${t} on the sphere`},
                      `trace: ${t.split(" (")[0]}`))
  }
  axisSel.value = "2"
  const shapeSel = mk("select", {class: "body-shape", "aria-label": "The body drawn as"})
  shapeSel.append(mk("option", {value: "box", title: "the uniform box with these principal moments"}, "box"),
                  mk("option", {value: "ellipsoid", title: "the inertia ellipsoid (I w, w) = 1"}, "ellipsoid"))
  // The settings' values as the server's state names them (app/state.py: body_speed, body_axis 1..3, body_shape).
  const settings = {body_speed: speedSel, body_axis: axisSel, body_shape: shapeSel}
  const bar = mk("div", {class: "body-bar"})
  bar.append(playBtn, backBtn, stepBtn, speedSel, axisSel, shapeSel)
  const status = mk("div", {class: "body-status", "aria-live": "polite"})
  //: Why a setting chosen was refused (one line per setting, empty: none), as the other controls' messages.
  const messages = {}
  for (const name of Object.keys(settings)) messages[name] = mk("div", {class: "ctl-msg body-msg", role: "alert"})
  root.append(canvasBox, bar, ...Object.values(messages), status)
  host.append(root)

  const ctx = canvas.getContext("2d")
  let data = null          // the decoded series (setData)
  let traces = [null, null, null]  // per principal axis: space coordinates per frame (Float64Array F*3)
  let pos = 0              // the frame shown, fractional: pos = i + f lies between recorded frames i and i + 1
  let playing = false
  let speed = DEFAULT_SPEED
  let traceAxis = 2
  let shape = "box"        // as the server says (the ellipsoid when no box has the moments)
  let yaw = -0.6, pitch = 0.35
  let last = null          // time of the last animation frame
  let raf = 0
  let period = -1          // the period whose section point is highlighted
  let draws = 0
  const stamps = []        // times of the animation frames drawn over the last second (fps)
  let scale = 1            // font scale (presentation mode)
  let wanted = false       // a paint is requested (paused: only on changes)

  function decode(d) {
    const F = d.frames | 0
    const out = {
      frames: F, samples: d.samples | 0, k0: d.k0 | 0, tStart: +d.t_start, period: +d.period,
      t: b64Floats(d.t), omega: b64Floats(d.omega), quaternion: b64Floats(d.quaternion), energy: b64Floats(d.energy),
      moments: d.moments, axes: d.axes, sides: d.box_sides, boxExists: d.box_exists !== false,
      ellipsoid: d.ellipsoid_axes || [1, 1, 1], status: d.status || "", complete: !!d.complete,
      lost: d.lost || [],
    }
    if (out.t.length !== F || out.omega.length !== 3 * F || out.quaternion.length !== 4 * F || out.energy.length !== F) {
      throw new Error(`body series: arrays of the wrong length for ${F} frames`)
    }
    let maxOmega = 0
    for (let i = 0; i < F; i++) {
      maxOmega = Math.max(maxOmega, Math.hypot(out.omega[3 * i], out.omega[3 * i + 1], out.omega[3 * i + 2]))
    }
    out.maxOmega = maxOmega || 1
    return out
  }

  const quatAt = (i) => {
    const q = data.quaternion
    return [q[4 * i], q[4 * i + 1], q[4 * i + 2], q[4 * i + 3]]
  }
  const axisBody = (i) => [data.axes[0][i], data.axes[1][i], data.axes[2][i]]  // column i: axis i in the body frame

  //: Points of a trace between two recorded frames (slerped, as the animation turns the body between them).
  const TRACE_SUB = 4

  function trace(i) {
    // Axis i in the space frame at every recorded frame and TRACE_SUB - 1 slerped orientations between them.
    if (!traces[i]) {
      const F = data.frames, a = axisBody(i), out = new Float64Array(3 * ((F - 1) * TRACE_SUB + 1))
      for (let j = 0; j < F; j++) {
        for (let m = 0; m < (j < F - 1 ? TRACE_SUB : 1); m++) {
          const q = m ? slerp(quatAt(j), quatAt(j + 1), m / TRACE_SUB) : quatAt(j)
          const v = mv(quatMatrix(...q), a), o = 3 * (j * TRACE_SUB + m)
          out[o] = v[0]; out[o + 1] = v[1]; out[o + 2] = v[2]
        }
      }
      traces[i] = out
    }
    return traces[i]
  }

  function state() {
    // The orientation, omega (body frame) and energy at the fractional frame pos.
    const F = data.frames
    const i = Math.min(F - 1, Math.max(0, Math.floor(pos)))
    const f = i >= F - 1 ? 0 : pos - i
    const j = Math.min(F - 1, i + 1)
    const q = f ? slerp(quatAt(i), quatAt(j), f) : quatAt(i)
    const o = data.omega, e = data.energy, t = data.t
    const lerp = (a, b) => a + f * (b - a)
    return {
      i, f, q,
      omega: [lerp(o[3 * i], o[3 * j]), lerp(o[3 * i + 1], o[3 * j + 1]), lerp(o[3 * i + 2], o[3 * j + 2])],
      energy: lerp(e[i], e[j]),
      t: data.tStart + lerp(t[i], t[j]),
    }
  }

  // --- drawing ---------------------------------------------------------------------------------------------

  function resize() {
    const r = canvasBox.getBoundingClientRect()
    const dpr = window.devicePixelRatio || 1
    const w = Math.max(1, Math.round(r.width * dpr)), h = Math.max(1, Math.round(r.height * dpr))
    if (canvas.width !== w || canvas.height !== h) {
      canvas.width = w
      canvas.height = h
    }
    return {w: r.width, h: r.height, dpr}
  }

  function draw() {
    const {w, h, dpr} = resize()
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0)
    ctx.clearRect(0, 0, w, h)
    ctx.fillStyle = "#ffffff"
    ctx.fillRect(0, 0, w, h)
    draws++
    const font = (px, weight = "") => `${weight} ${Math.round(px * scale)}px system-ui, "DejaVu Sans", sans-serif`
    if (!data) return  // the line under the canvas says why
    const V = viewMatrix(yaw, pitch)
    const st = state()
    const R = quatMatrix(...st.q)
    const ws = mv(R, st.omega), wn = Math.hypot(...ws)
    // What is shown, on one line or two (narrow): time, period, energy, |omega|.
    const k = data.k0 + Math.floor(pos / data.samples)
    const parts = [`t = ${st.t.toFixed(2)}`, `k = ${k}`, `T = ${fmtNum(st.energy, 5)}`, `|ω| = ${fmtNum(wn, 3)}`]
    ctx.font = font(14, "600")
    const labels = ctx.measureText(parts.join("   ")).width <= w - 16 ? [parts.join("   ")]
      : [parts.slice(0, 2).join("   "), parts.slice(2).join("   ")]
    // The sphere between the label (top) and the legend (two rows at the bottom).
    const top = (8 + 18 * labels.length) * scale, lh = 16 * scale, legH = 2 * lh + 8
    const x0 = 0, y1 = h - legH
    const cx = (x0 + w) / 2, cy = (top + y1) / 2
    const s = Math.max(10, 0.46 * Math.min(w - x0, y1 - top))  // the unit sphere's radius in pixels
    const P = (v) => {  // space -> [screen x, screen y, depth (> 0: behind the centre)]
      const u = mv(V, v)
      return [cx + s * u[0], cy - s * u[2], u[1]]
    }

    // The unit sphere: silhouette, parallels and meridians; the hidden half dashed and lighter.
    const circles = []
    for (const lat of [-60, -30, 0, 30, 60]) {
      const z = Math.sin(lat * Math.PI / 180), c = Math.cos(lat * Math.PI / 180)
      circles.push((a) => [c * Math.cos(a), c * Math.sin(a), z])
    }
    for (const lon of [0, 30, 60, 90, 120, 150]) {
      const cl = Math.cos(lon * Math.PI / 180), sl = Math.sin(lon * Math.PI / 180)
      circles.push((a) => [Math.cos(a) * cl, Math.cos(a) * sl, Math.sin(a)])
    }
    function sphere(back) {
      ctx.lineWidth = 1
      ctx.strokeStyle = back ? "rgba(120,130,145,0.22)" : "rgba(110,120,135,0.45)"
      ctx.setLineDash(back ? [3, 4] : [])
      for (const circle of circles) {
        ctx.beginPath()
        let pen = false
        for (let k = 0; k <= 72; k++) {
          const p = P(circle(2 * Math.PI * k / 72))
          if ((p[2] > 0) === back) {
            if (pen) ctx.lineTo(p[0], p[1]); else ctx.moveTo(p[0], p[1])
            pen = true
          } else pen = false
        }
        ctx.stroke()
      }
      ctx.setLineDash([])
      if (!back) {
        ctx.strokeStyle = "rgba(90,100,115,0.6)"
        ctx.beginPath()
        ctx.arc(cx, cy, s, 0, 2 * Math.PI)
        ctx.stroke()
        // The space frame's vertical axis z (the sphere's poles).
        const n = P([0, 0, 1.08]), m = P([0, 0, -1.08])
        ctx.strokeStyle = "rgba(90,100,115,0.35)"
        ctx.beginPath(); ctx.moveTo(m[0], m[1]); ctx.lineTo(n[0], n[1]); ctx.stroke()
        ctx.fillStyle = "#6b7685"
        ctx.font = font(11)
        ctx.fillText("z", n[0] - 12 * scale, n[1] + 4)  // left of the pole: an axis's number is right of its tip
      }
    }

    // The trace of a principal axis on the sphere, from the first frame to the one shown.
    function traceLine(back) {
      const tr = trace(traceAxis)
      ctx.strokeStyle = AXIS_COLOURS[traceAxis]
      ctx.globalAlpha = back ? 0.3 : 0.9
      ctx.lineWidth = back ? 1.2 : 1.8
      ctx.beginPath()
      let pen = false
      const n = Math.floor((st.i + st.f) * TRACE_SUB), last = tr.length / 3 - 1
      for (let j = 0; j <= n + 1 && j <= last; j++) {
        let v = [tr[3 * j], tr[3 * j + 1], tr[3 * j + 2]]
        if (j === n + 1) v = mv(R, axisBody(traceAxis))  // up to the orientation shown
        const p = P(v)
        if ((p[2] > 0) === back) {
          if (pen) ctx.lineTo(p[0], p[1]); else ctx.moveTo(p[0], p[1])
          pen = true
        } else if (pen) {
          ctx.lineTo(p[0], p[1])  // to the rim's neighbourhood: no gap where the trace crosses the silhouette
          pen = false
        }
      }
      ctx.stroke()
      ctx.globalAlpha = 1
    }

    // The principal axes (space directions) and the box (vertices in the principal frame, then body, space).
    const dirs = [0, 1, 2].map((i) => mv(R, axisBody(i)))
    const half = data.sides.map((x) => x / 2)
    const ell = data.ellipsoid.map((x) => ELLIPSOID_SIZE * x)
    const drawn = data.boxExists ? shape : "ellipsoid"  // a flat box is no body (the server says so too)
    const ext = drawn === "ellipsoid" ? ell : half  // where each axis leaves the body
    function arrow(a, b, colour, width, head) {
      ctx.strokeStyle = colour
      ctx.fillStyle = colour
      ctx.lineWidth = width
      ctx.beginPath(); ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); ctx.stroke()
      const dx = b[0] - a[0], dy = b[1] - a[1], L = Math.hypot(dx, dy)
      if (L < 2 || !head) return
      const ux = dx / L, uy = dy / L, hl = Math.min(head, 0.5 * L)
      ctx.beginPath()
      ctx.moveTo(b[0], b[1])
      ctx.lineTo(b[0] - hl * ux + 0.45 * hl * uy, b[1] - hl * uy - 0.45 * hl * ux)
      ctx.lineTo(b[0] - hl * ux - 0.45 * hl * uy, b[1] - hl * uy + 0.45 * hl * ux)
      ctx.closePath()
      ctx.fill()
    }
    function axis(i) {
      const d = dirs[i]
      const a = P(d.map((x) => x * ext[i])), b = P(d)
      arrow(a, b, AXIS_COLOURS[i], 2.6, 11 * scale)
      ctx.fillStyle = AXIS_COLOURS[i]
      ctx.font = font(13, "bold")
      ctx.fillText(String(i + 1), b[0] + 5, b[1] - 5)
    }
    function box() {
      const faces = []
      for (let i = 0; i < 3; i++) for (const sg of [-1, 1]) {
        const j = (i + 1) % 3, k = (i + 2) % 3
        const corner = (a, b) => {
          const v = [0, 0, 0]
          for (let c = 0; c < 3; c++) v[c] = sg * half[i] * dirs[i][c] + a * half[j] * dirs[j][c] + b * half[k] * dirs[k][c]
          return P(v)
        }
        const normal = mv(V, dirs[i].map((x) => sg * x))
        if (normal[1] >= 0) continue  // facing away: hidden behind the box's front faces (a convex body)
        faces.push({i, pts: [corner(-1, -1), corner(1, -1), corner(1, 1), corner(-1, 1)], normal})
      }
      for (const f of faces) {
        ctx.fillStyle = tint([0, 1, 2].map((c) => (c === f.i ? 1 : 0)), lambert(f.normal))
        ctx.strokeStyle = "#3a4554"
        ctx.lineWidth = 1.3
        ctx.beginPath()
        f.pts.forEach((p, n) => (n ? ctx.lineTo(p[0], p[1]) : ctx.moveTo(p[0], p[1])))
        ctx.closePath()
        ctx.fill()
        ctx.stroke()
      }
    }

    const RGB = AXIS_COLOURS.map((c) => [1, 3, 5].map((o) => parseInt(c.slice(o, o + 2), 16)))
    function tint(weights, lam) {
      // A face (or a patch of the ellipsoid) coloured by the principal axes it is normal to (weights summing to 1),
      // lit from above-left in front.
      const rgb = [0, 1, 2].map((c) => weights[0] * RGB[0][c] + weights[1] * RGB[1][c] + weights[2] * RGB[2][c])
      const shade = 0.72 + 0.28 * lam
      const mix = rgb.map((x) => Math.round((0.5 * x + 0.5 * 255) * shade))
      return `rgb(${mix[0]},${mix[1]},${mix[2]})`
    }
    const light = [-0.45, -0.75, 0.5].map((x) => x / Math.hypot(-0.45, -0.75, 0.5))
    const lambert = (n) => Math.max(0, -(n[0] * light[0] + n[1] * light[1] + n[2] * light[2]))
    function ellipsoid() {
      // The inertia ellipsoid (I w, w) = 1 (semi-axes 1 / sqrt(I_i), scaled): a mesh whose front patches are drawn
      // (a convex body hides its back), each tinted by the principal axes its normal points along, and its three
      // principal sections.
      const NU = 32, NV = 16
      const at = (u, v) => [ell[0] * Math.cos(v) * Math.cos(u), ell[1] * Math.cos(v) * Math.sin(u), ell[2] * Math.sin(v)]
      const space = (p) => [0, 1, 2].map((c) => p[0] * dirs[0][c] + p[1] * dirs[1][c] + p[2] * dirs[2][c])
      const grid = []
      for (let b = 0; b <= NV; b++) {
        const row = []
        for (let a = 0; a <= NU; a++) row.push(P(space(at(2 * Math.PI * a / NU, -Math.PI / 2 + Math.PI * b / NV))))
        grid.push(row)
      }
      for (let b = 0; b < NV; b++) for (let a = 0; a < NU; a++) {
        const p = at(2 * Math.PI * (a + 0.5) / NU, -Math.PI / 2 + Math.PI * (b + 0.5) / NV)
        const np = [p[0] / (ell[0] * ell[0]), p[1] / (ell[1] * ell[1]), p[2] / (ell[2] * ell[2])]
        const nl = Math.hypot(...np)
        const n = mv(V, space(np.map((x) => x / nl)))
        if (n[1] >= 0) continue  // facing away
        const wt = np.map((x) => (x / nl) ** 8), ws = wt[0] + wt[1] + wt[2]  // sharp, without steps
        ctx.fillStyle = ctx.strokeStyle = tint(wt.map((x) => x / ws), lambert(n))
        ctx.lineWidth = 0.8
        const q = [grid[b][a], grid[b][a + 1], grid[b + 1][a + 1], grid[b + 1][a]]
        ctx.beginPath()
        q.forEach((pt, m) => (m ? ctx.lineTo(pt[0], pt[1]) : ctx.moveTo(pt[0], pt[1])))
        ctx.closePath()
        ctx.fill()
        ctx.stroke()
      }
      // The principal sections (front halves): where the tinted patches meet, the body's "equators".
      ctx.strokeStyle = "rgba(40,50,65,0.75)"
      ctx.lineWidth = 1.2
      for (const [i, j] of [[0, 1], [1, 2], [2, 0]]) {
        ctx.beginPath()
        let pen = false
        for (let m = 0; m <= 96; m++) {
          const u = 2 * Math.PI * m / 96, pp = [0, 0, 0], nn = [0, 0, 0]
          pp[i] = ell[i] * Math.cos(u); pp[j] = ell[j] * Math.sin(u)
          nn[i] = Math.cos(u) / ell[i]; nn[j] = Math.sin(u) / ell[j]
          const front = mv(V, space(nn))[1] < 0
          const pt = P(space(pp))
          if (front) { if (pen) ctx.lineTo(pt[0], pt[1]); else ctx.moveTo(pt[0], pt[1]); pen = true } else pen = false
        }
        ctx.stroke()
      }
    }

    sphere(true)
    traceLine(true)
    const behind = [0, 1, 2].filter((i) => mv(V, dirs[i])[1] > 0)
    for (const i of behind) axis(i)  // pointing away: the body hides where they leave it
    if (drawn === "ellipsoid") ellipsoid()
    else box()
    for (const i of [0, 1, 2]) if (!behind.includes(i)) axis(i)
    sphere(false)
    traceLine(false)
    // The trace's current point.
    const cur = P(dirs[traceAxis])
    ctx.fillStyle = AXIS_COLOURS[traceAxis]
    ctx.strokeStyle = "#fff"
    ctx.lineWidth = 1.5
    ctx.beginPath(); ctx.arc(cur[0], cur[1], 4.5 * scale, 0, 2 * Math.PI); ctx.fill(); ctx.stroke()
    // omega in the space frame, over everything: its length is |omega| / max |omega| of the series (x 1.2).
    const tip = P(ws.map((x) => 1.2 * x / data.maxOmega))
    const o = P([0, 0, 0])
    arrow(o, tip, "#ffffff", 6, 0)
    arrow(o, tip, OMEGA_COLOUR, 2.8, 13 * scale)
    ctx.fillStyle = OMEGA_COLOUR
    ctx.font = font(14, "bold")
    if (wn > 1e-12) ctx.fillText("ω", tip[0] + 6, tip[1] + 4)

    ctx.fillStyle = "#1d2430"
    ctx.font = font(14, "600")
    labels.forEach((line, n) => ctx.fillText(line, 8, (18 + 18 * n) * scale))
    // The legend, two rows at the bottom: the axes with their moments, omega, the trace (each word in its colour).
    const m = data.moments.map((x) => fmtNum(x, 4))
    const rows = [[[AXIS_COLOURS[0], "1"], [AXIS_COLOURS[1], "2"], [AXIS_COLOURS[2], "3"],
                   [null, `principal axes, moments ${m[0]}, ${m[1]}, ${m[2]}`]],
                  [[OMEGA_COLOUR, "ω"], [null, "in space   "], [AXIS_COLOURS[traceAxis], "trace"],
                   [null, `of axis ${traceAxis + 1} on the sphere`]]]
    const rowWidth = (row, k) => row.reduce((x, [c, t]) => {
      ctx.font = font(12 * k, c ? "bold" : "")
      return x + (c ? 17 * scale * k : 0) + ctx.measureText(t).width + 6 * scale * k
    }, 0)
    rows.forEach((row, n) => {
      const y = h - 8 - (rows.length - 1 - n) * lh
      const k = Math.max(0.7, Math.min(1, (w - 16) / rowWidth(row, 1)))  // a narrow canvas: smaller words
      let x = 8
      for (const [c, t] of row) {
        if (c) {
          ctx.strokeStyle = c
          ctx.lineWidth = 2.6
          ctx.beginPath(); ctx.moveTo(x, y - 4 * scale); ctx.lineTo(x + 14 * scale * k, y - 4 * scale); ctx.stroke()
          x += 17 * scale * k
        }
        ctx.font = font(12 * k, c ? "bold" : "")
        ctx.fillStyle = c || "#1d2430"
        ctx.fillText(t, x, y)
        x += ctx.measureText(t).width + 6 * scale * k
      }
    })
  }

  // --- the animation ---------------------------------------------------------------------------------------

  function highlight() {
    // The section point of the period shown (the k-th point of the map: the start of period k). Once a period: the
    // point is drawn on the section plot's overlay level (app/views.py), so a move repaints no section point.
    if (!data || !onPoint) return
    const k = Math.min(Math.floor(pos / data.samples), Math.floor((data.frames - 1) / data.samples))
    if (k === period) return
    period = k
    const i = k * data.samples
    onPoint(data.omega[3 * i + 1], data.omega[3 * i + 2], data.k0 + k)
  }

  function frame(now) {
    raf = 0
    wanted = false
    // Not displayed (closed, or another tab open): no drawing; painted again when shown (show()).
    if (root.hidden || root.offsetParent === null) { last = null; return }
    if (!data) { draw(); return }
    if (playing) {
      if (last !== null) {
        pos += (now - last) / 1000 * speed * data.samples
        if (pos > data.frames - 1) pos = pos % (data.frames - 1 || 1)  // from the start again
      }
      last = now
      stamps.push(now)
      while (stamps.length && stamps[0] < now - 1000) stamps.shift()
    }
    draw()
    highlight()
    if (onFrame) onFrame()
    if (playing) raf = requestAnimationFrame(frame)
  }

  function paint() {
    if (!raf && !wanted) {
      wanted = true
      raf = requestAnimationFrame(frame)
    }
  }

  function setPlaying(on) {
    playing = on && !!data
    last = null
    stamps.length = 0
    playBtn.textContent = playing ? "Pause" : "Play"
    playBtn.setAttribute("aria-pressed", String(playing))
    paint()
  }

  function step(n) {
    if (!data) return
    setPlaying(false)
    pos = Math.min(data.frames - 1, Math.max(0, Math.round(pos) + n))
    paint()
  }

  playBtn.addEventListener("click", () => setPlaying(!playing))
  stepBtn.addEventListener("click", () => step(1))
  backBtn.addEventListener("click", () => step(-1))
  function setSetting(name, value) {
    // A setting's value in use (from the server, or chosen here without one).
    const v = String(value)
    if (name === "body_speed" && SPEEDS.includes(+v)) { speed = +v; last = null }
    else if (name === "body_axis" && ["1", "2", "3"].includes(v)) { traceAxis = +v - 1; paint() }
    else if (name === "body_shape" && (v === "box" || v === "ellipsoid")) { shape = v; paint() }
    else return
    settings[name].value = name === "body_axis" ? String(+v - 1) : v
  }
  for (const [name, sel] of Object.entries(settings)) {
    sel.addEventListener("change", () => {
      const v = name === "body_axis" ? String(+sel.value + 1) : sel.value
      if (onSetting) onSetting(name, v); else setSetting(name, v)
    })
  }
  let drag = null
  canvas.addEventListener("pointerdown", (e) => { drag = [e.clientX, e.clientY]; canvas.setPointerCapture(e.pointerId) })
  canvas.addEventListener("pointermove", (e) => {
    if (!drag) return
    yaw += (e.clientX - drag[0]) * 0.01
    pitch = Math.max(-1.5, Math.min(1.5, pitch + (e.clientY - drag[1]) * 0.01))
    drag = [e.clientX, e.clientY]
    paint()
  })
  const endDrag = () => { drag = null }
  canvas.addEventListener("pointerup", endDrag)
  canvas.addEventListener("pointercancel", endDrag)
  new ResizeObserver(() => paint()).observe(canvasBox)

  // --- what the page calls ---------------------------------------------------------------------------------

  const api = {
    el: root,
    /** A new series from the server (the payload of app/bodyview.py), or null/{} to drop the one shown. */
    setData(payload) {
      const had = !!data
      const keep = playing
      if (payload && payload.frames) {
        data = decode(payload)
        traces = [null, null, null]
        pos = 0
        period = -1
        setPlaying(keep || !had)  // a new series plays at once
      } else {
        data = null
        traces = [null, null, null]
        period = -1
        setPlaying(false)
        if (onPoint) onPoint(null, null, null)
      }
      for (const b of [playBtn, stepBtn, backBtn]) b.disabled = !data
      paint()
    },
    /** A line under the canvas (what the server says: computing, why there is no series). */
    setStatus(text, lost = false) {
      status.textContent = text || ""
      status.title = text || ""
      status.classList.toggle("lost", !!lost)
      if (!data) paint()
    },
    setScale(x) { scale = x; paint() },
    /** A setting's value in use (body_speed, body_axis "1".."3", body_shape), as the server's state holds it. */
    setSetting,
    /** The settings' selects and message lines by name (the page shows refusals there as for its controls). */
    settings, messages,
    show(on) {
      root.hidden = !on
      if (on) paint()
    },
    play() { setPlaying(true) },
    pause() { setPlaying(false) },
    step,
    seek(i) { if (data) { pos = Math.min(data.frames - 1, Math.max(0, i)); paint() } },
  }

  // The test hook (read-only numbers and a few verbs): one body view per page.
  window.bilimovichBody = {
    get frame() { return data ? Math.floor(pos) : -1 },
    get position() { return pos },
    get frames() { return data ? data.frames : 0 },
    get samples() { return data ? data.samples : 0 },
    get k0() { return data ? data.k0 : -1 },
    get playing() { return playing },
    get fps() { return stamps.length > 1 ? 1000 * (stamps.length - 1) / (stamps[stamps.length - 1] - stamps[0]) : 0 },
    get draws() { return draws },
    get period() { return period },
    get speed() { return speed },
    get shape() { return data && !data.boxExists ? "ellipsoid" : shape },
    get traceAxis() { return traceAxis + 1 },
    /** The recorded quaternion (w, x, y, z) of frame i, as the page holds it (float32). */
    quaternion(i) { return data ? quatAt(i) : null },
    /** The orientation drawn now (slerped between recorded frames). */
    drawnQuaternion() { return data ? state().q : null },
    /** The section point highlighted: [q, r, k], or null. */
    point() {
      if (!data || period < 0) return null
      const i = period * data.samples
      return [data.omega[3 * i + 1], data.omega[3 * i + 2], data.k0 + period]
    },
    play: () => api.play(),
    pause: () => api.pause(),
    step: (n = 1) => api.step(n),
    seek: (i) => api.seek(i),
  }
  api.setData(null)
  return api
}
