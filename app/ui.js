// The explorer's page: layout, every control, messages, status and buttons in one component
// (app/ui.py). The server holds the values in use; this module only shows them and sends what
// the user typed (model.send_msg), so a refused value never stays in a box as if it were used.
// Text from the server is always set as textContent, never as HTML.

const CSS = `
:host { display: block; width: 100%; height: 100%; }
* { box-sizing: border-box; }
.app { display: grid; grid-template-columns: 300px minmax(0, 1fr); grid-template-rows: auto minmax(0, 1fr);
  height: 100vh; font-family: system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif;
  font-size: 13px; color: #1d2430; background: #fff; }
.app.side-collapsed { grid-template-columns: 0 minmax(0, 1fr); }
.app.side-collapsed .side { visibility: hidden; padding: 0; border: 0; }
header { grid-column: 1 / 3; display: flex; align-items: center; gap: 6px; padding: 4px 10px;
  background: #2c5f8a; color: #fff; min-height: 40px; flex-wrap: wrap; }
header .title { font-weight: 600; font-size: 1.15em; margin-right: 8px; white-space: nowrap; }
header button { background: transparent; color: #fff; border: 1px solid rgba(255,255,255,.45); border-radius: 4px;
  padding: 4px 8px; cursor: pointer; font: inherit; white-space: nowrap; }
header button:hover { background: rgba(255,255,255,.12); }
header .tab-btn[aria-selected="true"] { background: #fff; color: #2c5f8a; border-color: #fff; }
header .spacer { flex: 1; }
.side { overflow-y: auto; padding: 8px 12px 24px; border-right: 1px solid #d8dde5; background: #f7f9fb; min-width: 0; }
.side h3 { font-size: 1em; margin: 14px 0 4px; color: #2c5f8a; }
.main { overflow: auto; min-height: 0; min-width: 0; padding: 6px 10px; display: flex; flex-direction: column; }
.pane { display: flex; flex-direction: column; gap: 4px; flex: 1 1 auto; min-height: 0; }
.pane[hidden] { display: none; }
.ctl { margin: 6px 0; }
.ctl label, .ctl .lab { display: block; font-size: .92em; color: #3a4554; margin-bottom: 2px; }
.ctl .row { display: flex; gap: 6px; align-items: center; }
.ctl input[type=range] { flex: 1 1 auto; min-width: 60px; }
.ctl input.num, .ctl input.txt { font: inherit; padding: 3px 6px; border: 1px solid #b9c2cf; border-radius: 4px;
  width: 100%; min-width: 0; }
.ctl.float input.num { width: 7.5em; flex: 0 0 auto; }
.ctl select { font: inherit; padding: 3px; width: 100%; }
.ctl.refused input.num, .ctl.refused input.txt { border-color: #b02a37; background: #fff5f5; }
.ctl-msg { color: #842029; background: #f8d7da; border: 1px solid #f5c2c7; border-radius: 4px; padding: 3px 6px;
  margin-top: 3px; font-size: .9em; }
.ctl-msg:empty { display: none; }
.seg { display: inline-flex; flex-wrap: wrap; max-width: 100%; border: 1px solid #b9c2cf; border-radius: 4px;
  overflow: hidden; }
.seg button { font: inherit; border: 0; padding: 3px 9px; background: #fff; cursor: pointer; }
.seg button[aria-pressed="true"] { background: #2c5f8a; color: #fff; }
.ctl.check label { display: flex; gap: 6px; align-items: center; font-size: 1em; }
.help { color: #4a5566; font-size: .92em; margin: 2px 0; }
.bar { display: flex; flex-wrap: wrap; gap: 8px; align-items: flex-end; }
.bar .ctl { margin: 0; }
.bar .ctl.int input.num { width: 6em; }
.figure-bar { display: inline-flex; flex-wrap: wrap; gap: 3px; align-items: center; max-width: 100%; }
.figure-bar input.num { width: 4.6em; }
.figure-bar input.fig-dpi { width: 3.6em; }
.bar .ctl-selected .btn-no-selection { margin-left: 4px; padding: 3px 8px; }
/* The section's bar in few rows: each label beside its control, the buttons a little narrower. */
.pane-section > .bar { gap: 4px 6px; align-items: center; }
.pane-section > .bar .ctl { display: flex; align-items: center; gap: 6px; }
.pane-section > .bar .ctl > label, .pane-section > .bar .ctl > .lab { margin: 0; }
.pane-section > .bar button.act { padding: 3px 8px; }
button.act { font: inherit; padding: 4px 12px; border-radius: 4px; border: 1px solid #2c5f8a; background: #2c5f8a;
  color: #fff; cursor: pointer; }
button.act.warn { background: #b8860b; border-color: #b8860b; }
button.act.light { background: #fff; color: #2c5f8a; }
button.act:disabled { opacity: .45; cursor: not-allowed; }
button.act[hidden] { display: none; }
button.act.light[aria-pressed="true"]:disabled { opacity: 1; background: #dbe9f5; color: #1d4466; cursor: default; }
.error-box { color: #842029; background: #f8d7da; border: 1px solid #f5c2c7; border-radius: 4px; padding: 5px 10px; }
.error-box:empty, .warnings:empty { display: none; }
.warn-box { color: #664d03; background: #fff3cd; border: 1px solid #ffecb5; border-radius: 4px; padding: 5px 10px;
  margin-bottom: 3px; }
.warn-box.level-error { color: #842029; background: #f8d7da; border-color: #f5c2c7; }
.status-line { font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-size: .95em; min-height: 1.3em;
  white-space: pre-wrap; flex: none; }
/* The plot first and large: the plot's column takes what the side column (k-series, results, forms) leaves; the
   side column grows with the screen (282 px at 1280, 422 px at 1920; the section's: below). */
.app { --side: clamp(280px, 22vw, 520px); }
.plots { flex: 1 1 0; min-height: 300px; display: grid; grid-template-columns: minmax(0, 1fr) var(--side);
  gap: 10px; }
.plot-col { display: flex; flex-direction: column; gap: 2px; min-height: 0; min-width: 0; }
.side-col { display: flex; flex-direction: column; gap: 4px; min-height: 0; min-width: 0; }
.plot-section, .plot-series, .plot-analysis { min-height: 0; min-width: 0; position: relative; display: flex; }
.plot-col > .plot-section, .plot-col > .plot-analysis { flex: 1 1 0; min-height: 260px; }
.side-col > .plot-series { flex: 1 1 0; min-height: 250px; }
.plot-key { flex: none; }
/* The section's side column holds the orbit table too: a little wider (340 px at 1280, 460 px at 1920). */
.pane-section { --side: clamp(340px, 24vw, 520px); }
.plot-key > :empty, .plot-key > [hidden] { display: none; }
/* Under the k-series: the orbit table, the layers' statuses and legends, scrolled in their box. */
.notes { flex: 0 1 auto; max-height: 45%; overflow: auto; min-height: 0; }
.notes .legend { margin-top: 3px; }
/* There an orbit takes two lines (period, type, q, r; then its multipliers): a row fits the column's width. */
.notes .orbits { max-height: 14em; }
.notes .orbit-table { display: block; }
.notes .orbit-table tr { display: grid; grid-template-columns: 3.6em minmax(0, 1.3fr) minmax(0, 1fr) minmax(0, 1fr);
  column-gap: 4px; border-bottom: 1px solid #eef1f5; }
.notes .orbit-table tr:first-child { position: sticky; top: 0; background: #fff; z-index: 1; }
.notes .orbit-table :is(th, td) { padding: 0; white-space: normal; position: static; }
.notes .orbit-table :is(th, td):last-child { grid-column: 2 / -1; }
.plot-series { flex-direction: column; }
.plot-series .cap { font-size: .92em; color: #3a4554; }
.series-head { display: flex; gap: 10px; align-items: baseline; flex-wrap: wrap; }
.series-head .ctl { margin: 0; white-space: nowrap; }
/* The body in 3-D needs height: the plots take the screen below the bars (the legends scroll under them). */
.app.body-open .plots { min-height: max(300px, calc(100vh - 320px)); }
.app.body-open .notes { max-height: 25%; }
.series-chart { flex: 1 1 0; min-height: 70px; position: relative; }
.series-chart svg { position: absolute; inset: 0; width: 100%; height: 100%; overflow: visible; }
.series-chart text { font-size: 11px; fill: #3a4554; }
.app.present .series-chart text { font-size: 15px; }
.series-chart .axis { stroke: #9aa5b4; stroke-width: 1; }
/* An analysis tab: the plot's column (the plot, its key) and the side column (form, Run, results, help). */
.pane-analysis { display: grid; grid-template-columns: minmax(0, 1fr) var(--side); gap: 10px; }
.pane-analysis > .plot-col { min-height: 300px; }
.analysis-side { overflow-y: auto; overflow-x: hidden; }
.analysis-side .form .ctl { flex: 1 1 130px; min-width: 120px; }
.analysis-side .bar { gap: 4px 6px; }
.analysis-side .result { font-size: .95em; }
.legend { font-size: .9em; color: #3a4554; }
.basin-item { margin-right: 12px; white-space: nowrap; }
.legend span.sw { display: inline-block; width: 12px; height: 12px; border: 1px solid #999; vertical-align: -2px;
  margin: 0 3px 0 8px; }
.form { display: flex; flex-wrap: wrap; gap: 4px 14px; }
.form .ctl { flex: 0 1 170px; min-width: 140px; }
.form .ctl.check { flex-basis: 100%; }
.form .ctl.text { flex-basis: 200px; }
progress { width: 100%; height: 10px; }
progress[hidden] { display: none; }
.result div { margin: 1px 0; }
.orbits { flex: none; max-height: 6.6em; overflow: auto; border-top: 1px solid #d8dde5; }
.orbits[hidden] { display: none; }
.legend[hidden] { display: none; }
.orbits table { border-collapse: collapse; font-size: .92em; width: 100%; }
.orbits th, .orbits td { text-align: left; padding: 1px 8px 1px 0; white-space: nowrap; }
.orbits th { position: sticky; top: 0; background: #fff; color: #3a4554; font-weight: 600; }
.orbit-status { font-size: .92em; color: #3a4554; min-height: 1.2em; }
.app.present { font-size: 18px; }
.app.present header .title { font-size: 1.25em; }
/* One header row at 1280x720 in presentation mode: the header's words a little smaller than the page's (they are
   read once); while a tour shows, its menu is in the tour's box in place of its title (showView). */
.app.present header { font-size: 14px; gap: 6px; }
.app.present header button { padding: 3px 8px; }
.tour .tour-head select.tour-choice { font: inherit; color: #0a58ca; padding: 1px 2px; max-width: 60%;
  border: 1px solid #9ec5fe; border-radius: 4px; background: #fff; }
/* The status line on one line (the whole text in its tooltip): the plot keeps its height. */
.status-line { white-space: nowrap; overflow: hidden; text-overflow: ellipsis; }
/* A tall screen (1920x1080) has the room for the whole text. */
@media (min-height: 900px) { .status-line { white-space: pre-wrap; } }
.analysis-side .status-line { white-space: pre-wrap; }
.app.present .status-line { font-size: 1em; }
/* At 1280x720 the table sits just under the plot: smaller rows show the header and 3-4 orbits without scrolling. */
.app.present .orbits { font-size: .8em; }
/* Play a parameter: one compact row over the section. */
.play-bar { display: flex; flex-wrap: wrap; gap: 6px; align-items: flex-end; }
.play-bar .ctl { margin: 0; }
.play-bar .ctl label, .play-bar .ctl .lab { font-size: .85em; margin: 0; }
.play-bar .ctl.text input.txt { width: 7.5em; }  /* the placeholder "value − 0.05" whole */
.play-bar .ctl.int input.num { width: 4em; }
.play-bar .ctl.select select { width: auto; }
.play-bar .ctl-msg { position: absolute; z-index: 5; }
.play-status { font-size: .9em; color: #3a4554; align-self: center; }
/* A guided tour: its step heads the main area on every tab (a step may open an analysis tab) and stays in view when
   the tab is scrolled; readable from the back of a room in presentation mode. */
.tour-area { position: sticky; top: -6px; z-index: 20; flex: none; background: #fff; }
.tour { border: 2px solid #0a58ca; border-radius: 6px; background: #f0f6ff; padding: 6px 10px; margin-bottom: 4px; }
.tour[hidden] { display: none; }
.tour .tour-head { display: flex; gap: 8px; align-items: center; font-weight: 600; color: #0a58ca; }
.tour .tour-head .spacer { flex: 1; }
.tour .tour-text { margin: 4px 0 2px; line-height: 1.35; }
.app.present .tour .tour-text { font-size: 1.05em; }
/* One header row at 1280 px: the menu as wide as its first words (a tour's title is shown whole in the tour's box). */
header select.tour-choice { font: inherit; padding: 2px; width: 150px; }
header .tabs { display: flex; gap: 4px; }
/* One header row at 1280x720 in presentation mode: the tour menu only while a tour shows (choose one before). */
.app.present:not(.touring) header select.tour-choice { display: none; }
.app.present.touring:not(.tour-plays) .pane-section > .bar { display: none; }
/* An analysis tab in a tour: the step's text says what the tab shows, and the tour has set it (and pressed Run): the
   plot gets the room of the tab's help (and in presentation mode of its form; both back outside the tour). */
.app.touring .pane-analysis .analysis-help, .app.present.touring .pane-analysis .form { display: none; }
.app.present .play-bar { display: none; }
/* The figure download (a file for a paper, not for the room) is left out of the projected section's bar: at
   1280x720 it took the bar to a third row and the plot under half the screen. */
.app.present .pane-section .figure-bar { display: none; }
/* Presentation: the side columns' words a little smaller than the page's (the plot is what the room reads), and the
   section's bar in two rows, each label beside its control, in the header's size. */
.app.present .side-col { font-size: 15px; }
.app.present .pane-section > .bar { font-size: 14px; }
.app.present .warn-box { font-size: 15px; padding: 3px 10px; }
.app.present .tour { padding: 4px 10px; }
.app.present .tour .tour-text { margin: 2px 0 0; }
.tour-message { font-size: .9em; color: #3a4554; margin-bottom: 4px; white-space: pre-line; }
.tour-message.problem { color: #664d03; background: #fff3cd; border: 1px solid #ffecb5; border-radius: 4px;
  padding: 3px 8px; }
.tour-message:empty { display: none; }
`

const TAB_TITLES = {section: "Poincaré section", lyapunov: "Lyapunov spectrum", bifurcation: "Bifurcation diagram",
                    chart: "Chart of regimes", bench: "Speed vs accuracy"}
const SIDE_GROUPS = [["scene", null], ["inertia", "Inertia tensor"], ["forcing", "Constraint and forcing"],
                     ["numerics", "Numerics"], ["layers", "Layers"]]

function h(tag, attrs = {}, ...kids) {
  const e = document.createElement(tag)
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") e.className = v
    else if (k === "text") e.textContent = v
    else if (v !== null && v !== undefined && v !== false) e.setAttribute(k, v === true ? "" : v)
  }
  for (const kid of kids) if (kid) e.append(kid)
  return e
}

// A figure of a tab's main plot, written by the server (app/figures.py) and sent as a download: the format, the
// size in pixels and the resolution (dots per inch: the fonts are set in points).
function figureBar(send, tabOf) {
  const fmt = h("select", {class: "fig-format", "aria-label": "Figure format"},
                h("option", {value: "png", text: "PNG"}), h("option", {value: "svg", text: "SVG"}))
  const num = (cls, value, label) => h("input", {class: `num ${cls}`, type: "number", value, "aria-label": label})
  const w = num("fig-width", 1600, "Figure width (pixels)")
  const hgt = num("fig-height", 1000, "Figure height (pixels)")
  const dpi = num("fig-dpi", 200, "Figure resolution (dots per inch)")
  const btn = h("button", {class: "act light btn-figure", text: "Download figure",
                           title: "The plot as a PNG or SVG file of this size (pixels) at this resolution (dpi)"})
  btn.addEventListener("click", () => send({action: "download", what: "figure", tab: tabOf(),
                                            value: `${fmt.value} ${w.value}x${hgt.value} ${dpi.value}`}))
  return h("span", {class: "figure-bar"}, btn, fmt, w, h("span", {text: "×"}), hgt, h("span", {text: "px"}), dpi,
           h("span", {text: "dpi"}))
}

export function render({model, el}) {
  const controls = {}          // name -> {spec, box, set(value), focusValue()}
  const send = (data) => model.send_msg(data)
  const commit = (name, text) => send({commit: name, text: text})

  // --- one control ---------------------------------------------------------------------------
  function control(spec) {
    const wrap = h("div", {class: `ctl ${spec.kind} ctl-${spec.name}`})
    const msg = h("div", {class: "ctl-msg", role: "alert"})
    const id = `c-${spec.name}`
    const entry = {spec, wrap, msg}
    if (spec.kind === "float") {
      const range = h("input", {type: "range", min: spec.lo, max: spec.hi, step: spec.step, "aria-label": spec.label})
      const num = h("input", {class: "num", type: "text", inputmode: "decimal", id})
      wrap.append(h("label", {for: id, text: spec.label}), h("div", {class: "row"}, range, num), msg)
      range.addEventListener("input", () => { num.value = range.value })        // live while dragging
      range.addEventListener("change", () => { num.dataset.sent = range.value; commit(spec.name, range.value) })
      entry.inputs = [num]
      entry.set = (v) => { num.value = v; num.dataset.sent = v; range.value = v }
    } else if (spec.kind === "int" || spec.kind === "text") {
      const num = h("input", {class: spec.kind === "int" ? "num" : "txt", type: "text", id,
                              inputmode: spec.kind === "int" ? "numeric" : null, placeholder: spec.placeholder || null})
      wrap.append(h("label", {for: id, text: spec.label}), num, msg)
      entry.inputs = [num]
      entry.set = (v) => { num.value = v; num.dataset.sent = v }
    } else if (spec.kind === "select") {
      const sel = h("select", {id})
      for (const [v, lab] of spec.options) sel.append(h("option", {value: v, text: lab}))
      sel.addEventListener("change", () => commit(spec.name, sel.value))
      wrap.append(h("label", {for: id, text: spec.label}), sel, msg)
      entry.set = (v) => { sel.value = v }
    } else if (spec.kind === "radio") {
      const seg = h("div", {class: "seg", role: "group", "aria-label": spec.label})
      const buttons = spec.options.map(([v, lab]) => {
        const b = h("button", {type: "button", "data-value": v, text: lab})
        b.addEventListener("click", () => commit(spec.name, v))
        seg.append(b)
        return b
      })
      wrap.append(h("span", {class: "lab", text: spec.label}), seg, msg)
      entry.set = (v) => { for (const b of buttons) b.setAttribute("aria-pressed", String(b.dataset.value === v)) }
    } else if (spec.kind === "check") {
      const box = h("input", {type: "checkbox", id})
      box.addEventListener("change", () => commit(spec.name, box.checked))
      wrap.append(h("label", {for: id}, box, document.createTextNode(spec.label)), msg)
      entry.set = (v) => { box.checked = !!v }
    }
    for (const inp of entry.inputs || []) {
      // Sent when changed, and always while the control shows a refusal: retyping the value in use answers it
      // (the server clears the message), even though the box already showed that value.
      const go = () => {
        if (inp.value !== inp.dataset.sent || wrap.classList.contains("refused")) {
          inp.dataset.sent = inp.value
          commit(spec.name, inp.value)
        }
      }
      inp.addEventListener("change", go)
      inp.addEventListener("keydown", (e) => { if (e.key === "Enter") go() })
    }
    if (spec.help) wrap.append(h("div", {class: "help", text: spec.help}))
    controls[spec.name] = entry
    return wrap
  }

  // --- skeleton ---------------------------------------------------------------------------------
  const style = h("style", {text: CSS + BODY_CSS})
  const app = h("div", {class: "app"})
  const tabButtons = {}
  const nav = h("nav", {class: "tabs", role: "tablist"})
  for (const t of model.spec.tabs) {
    const b = h("button", {class: "tab-btn", role: "tab", "data-tab": t, text: TAB_TITLES[t] || t})
    b.addEventListener("click", () => { showTab(t); send({action: "tab", tab: t}) })
    tabButtons[t] = b
    nav.append(b)
  }
  const sideBtn = h("button", {class: "btn-sidebar", title: "Show or hide the controls", text: "☰ Controls"})
  sideBtn.addEventListener("click", () => app.classList.toggle("side-collapsed"))
  const presentBtn = h("button", {class: "btn-present", title: "Larger fonts, controls hidden (for a projector)"})
  presentBtn.addEventListener("click", () => {
    const on = !app.classList.contains("present")
    setPresentation(on)
    send({action: "presentation", on})
  })
  // Tours: choose one (the paper's and a teacher's own), or upload a tours file (read here, sent as text).
  // The menu's last entry loads a file (one header row at 1280 px: no button of its own).
  const UPLOAD = ":upload"  // not a tour id (app/state.py's _ID: letters, digits, _ . -)
  const tourChoice = h("select", {class: "tour-choice", "aria-label": "Guided tour"})
  const tourFile = h("input", {type: "file", class: "tour-file", accept: ".json,application/json", hidden: true})
  tourChoice.addEventListener("change", () => {
    if (tourChoice.value !== UPLOAD) send({action: "tour", value: tourChoice.value})
    else { tourChoice.value = tourChoice.dataset.shown || ""; tourFile.click() }
  })
  tourFile.addEventListener("change", async () => {
    const f = tourFile.files && tourFile.files[0]
    if (f) send({action: "tour_file", value: await f.text()})
    tourFile.value = ""
  })
  const header = h("header", {}, sideBtn, h("span", {class: "title", text: "Bilimovich Explorer"}), nav,
                   h("span", {class: "spacer"}), tourChoice, tourFile, presentBtn)

  const side = h("aside", {class: "side"})
  const byArea = {}
  for (const s of model.spec.controls) (byArea[s.area] = byArea[s.area] || []).push(s)
  const sceneInfo = h("div", {class: "help scene-info"})
  for (const [area, title] of SIDE_GROUPS) {
    if (title) side.append(h("h3", {text: title}))
    for (const s of byArea[area] || []) side.append(control(s))
    if (area === "scene") side.append(sceneInfo)
  }

  // Section pane.
  const stopBtn = h("button", {class: "act warn btn-stop", text: "Stop"})
  stopBtn.addEventListener("click", () => send({action: "stop"}))
  const clearBtn = h("button", {class: "act light btn-clear", text: "Clear clicked points"})
  clearBtn.addEventListener("click", () => send({action: "clear"}))
  const csvBtn = h("button", {class: "act light btn-csv", text: "Download section CSV"})
  csvBtn.addEventListener("click", () => send({action: "download", what: "section"}))
  const findBtn = h("button", {class: "act light btn-find-orbits", text: "Find orbits in view"})
  findBtn.addEventListener("click", () => send({action: "find_orbits"}))
  const clearOrbBtn = h("button", {class: "act light btn-clear-orbits", text: "Clear orbits"})
  clearOrbBtn.addEventListener("click", () => send({action: "clear_orbits"}))
  const orbCsvBtn = h("button", {class: "act light btn-orbits-csv", text: "Download orbits CSV"})
  orbCsvBtn.addEventListener("click", () => send({action: "download", what: "orbits"}))
  const clearManBtn = h("button", {class: "act light btn-clear-manifolds", text: "Clear manifolds", hidden: true})
  clearManBtn.addEventListener("click", () => send({action: "clear_manifolds"}))
  const manCsvBtn = h("button", {class: "act light btn-manifolds-csv", text: "Download manifolds CSV", hidden: true})
  manCsvBtn.addEventListener("click", () => send({action: "download", what: "manifolds"}))
  const secBar = h("div", {class: "bar"})
  for (const s of byArea.section || []) secBar.append(control(s))
  // No trajectory selected (sel=none): nothing ringed in the plot, the k-series empty; typed "none" does the same.
  const noSelBtn = h("button", {class: "act light btn-no-selection", text: "None",
                                title: "Select no trajectory: nothing ringed in the plot, no k-series"})
  noSelBtn.addEventListener("click", () => commit("selected", "none"))
  if (controls.selected) controls.selected.inputs[0].after(noSelBtn)
  const basNpzBtn = h("button", {class: "act light btn-basins-npz", text: "Download basins NPZ", hidden: true})
  basNpzBtn.addEventListener("click", () => send({action: "download", what: "basins"}))
  const ftleNpzBtn = h("button", {class: "act light btn-ftle-npz", text: "Download FTLE NPZ", hidden: true})
  ftleNpzBtn.addEventListener("click", () => send({action: "download", what: "ftle"}))
  secBar.append(stopBtn, clearBtn, csvBtn, findBtn, clearOrbBtn, orbCsvBtn, clearManBtn, manCsvBtn, basNpzBtn,
                ftleNpzBtn,
                figureBar(send, () => "section"))
  // Play a parameter: its settings are controls (area "play"); Play/Pause and Step are actions.
  const playBtn = h("button", {class: "act btn-play", text: "▶ Play"})
  playBtn.addEventListener("click", () => send({action: playBtn.dataset.playing === "1" ? "pause" : "play"}))
  const stepBtn = h("button", {class: "act light btn-step", text: "Step +1", title: "One frame on, as a still"})
  stepBtn.addEventListener("click", () => send({action: "step"}))
  const playStatus = h("span", {class: "play-status", "aria-live": "polite"})
  const playBar = h("div", {class: "play-bar"})
  for (const s of byArea.play || []) playBar.append(control(s))
  playBar.append(playBtn, stepBtn, playStatus)
  let lastShown = -1
  // The guided tour's step.
  const tourBack = h("button", {class: "act light btn-tour-back", text: "← Back"})
  tourBack.addEventListener("click", () => send({action: "tour_step", value: "back"}))
  const tourNext = h("button", {class: "act btn-tour-next", text: "Next →"})
  tourNext.addEventListener("click", () => send({action: "tour_step", value: "next"}))
  const tourClose = h("button", {class: "act light btn-tour-close", text: "✕", title: "Leave the tour"})
  tourClose.addEventListener("click", () => send({action: "tour", value: ""}))
  const tourCount = h("span", {class: "tour-count"})
  const tourText = h("div", {class: "tour-text", "aria-live": "polite"})
  const tourHead = h("div", {class: "tour-head"}, tourCount, h("span", {class: "spacer"}), tourBack, tourNext,
                     tourClose)
  const tourBox = h("div", {class: "tour", hidden: true, role: "region", "aria-label": "Guided tour"}, tourHead, tourText)
  function placeTourChoice() {
    // A tour shown: the menu (showing the tour's title) heads the tour's box, so the header keeps one row at
    // 1280x720; else it is in the header.
    const inBox = !tourBox.hidden
    if (inBox !== (tourChoice.parentElement === tourHead)) {
      if (inBox) tourHead.prepend(tourChoice)
      else header.insertBefore(tourChoice, tourFile)
    }
  }
  // What the page says about the tours (a file loaded, or a problem: a file, tour or step the link names not there).
  const tourMsg = h("div", {class: "tour-message", role: "status"})
  const tourArea = h("div", {class: "tour-area"}, tourBox, tourMsg)
  // Arrow keys move through the tour (not while typing in a box).
  document.addEventListener("keydown", (e) => {
    if (tourBox.hidden || e.altKey || e.ctrlKey || e.metaKey) return
    const t = e.composedPath()[0]
    if (t && (t.tagName === "INPUT" || t.tagName === "SELECT" || t.tagName === "TEXTAREA")) return
    if (e.key === "ArrowRight" || e.key === "PageDown") { send({action: "tour_step", value: "next"}); e.preventDefault() }
    if (e.key === "ArrowLeft" || e.key === "PageUp") { send({action: "tour_step", value: "back"}); e.preventDefault() }
  })
  const secErrors = h("div", {class: "error-box main-error", role: "alert"})
  const warnings = h("div", {class: "warnings reliability-warning"})
  const status = h("div", {class: "status-line", "aria-live": "polite"})
  const plotSection = h("div", {class: "plot-section"})
  const seriesCap = h("div", {class: "cap series-caption"})
  const charts = [["q", "q_k", "#1f77b4"], ["r", "r_k", "#ff7f0e"], ["T", "T_k (energy)", "#2ca02c"]].map(
    ([key, label, colour]) => ({key, label, colour, box: h("div", {class: `series-chart series-${key}`})}))
  // The right column's head: the body view's toggle (area "body") and what the column shows.
  const seriesHead = h("div", {class: "series-head"}, ...(byArea.body || []).map((s) => control(s)), seriesCap)
  const plotSeries = h("div", {class: "plot-series"}, seriesHead, ...charts.map((c) => c.box))
  // The body in 3-D (app/body.js) in the k-series' place while it is open; it moves the section point of the period
  // it shows in the section plot itself (the figure's body_source, written in place: no message to the server).
  function bodyPoint(q, r) {
    const doc = window.Bokeh && Bokeh.documents && Bokeh.documents[0]
    const src = doc && doc.get_model_by_name("body_source")
    if (!src) return
    const cols = q === null ? {q: [], r: []} : {q: [q], r: [r]}
    for (const [k, v] of Object.entries(cols)) src.data instanceof Map ? src.data.set(k, v) : (src.data[k] = v)
    src.change.emit()
  }
  const bodyView = createBodyView(plotSeries, {onPoint: bodyPoint, onSetting: commit})
  // Its settings (area "bodyview": speed, axis traced, drawing) are controls like the others: chosen in its bar,
  // sent, and shown as the server answers (the value in use, a refusal under the bar).
  for (const [name, sel] of Object.entries(bodyView.settings)) {
    controls[name] = {spec: {name}, wrap: sel, msg: bodyView.messages[name], set: (v) => bodyView.setSetting(name, v)}
  }
  const eqLegend = h("div", {class: "legend"})
  for (const [t, c] of model.spec.eq_colors) {
    eqLegend.append(h("span", {text: "◆", style: `color:${c};margin-left:8px`}), document.createTextNode(" " + t))
  }
  eqLegend.prepend(document.createTextNode("◆ Frozen-field equilibria (t fixed at t0; dashed tracks over one " +
                                          "period; a heuristic for slow forcing, not orbits of the map):"))
  const orbLegend = h("div", {class: "legend orbit-legend",
    text: "Periodic orbits of the Poincaré map P (fixed points of P^n, found by Newton; magenta rings, not " +
          "diamonds): ● stable orbit, ○ unstable or elliptic orbit, ✕ saddle orbit of the map (flip saddle: the " +
          "expanding multiplier is negative). Hover a mark for its multipliers."})
  const manLegend = h("div", {class: "legend manifold-legend"},
    document.createTextNode("Manifolds of a saddle (click its ✕ with 'draws a saddle's manifolds'): "),
    h("span", {text: "━", style: "color:#e8590c"}), document.createTextNode(" unstable, "),
    h("span", {text: "━", style: "color:#0b7285"}), document.createTextNode(" stable, "),
    h("span", {text: "◆"}), document.createTextNode(" homoclinic points."))
  const manStatus = h("div", {class: "orbit-status manifold-status", "aria-live": "polite"})
  const basStatus = h("div", {class: "orbit-status basin-status", "aria-live": "polite"})
  const ftleStatus = h("div", {class: "orbit-status ftle-status", "aria-live": "polite"})
  const densLegend = h("div", {class: "legend density-legend", hidden: true,
    text: "Density image: section points per pixel of the view, log scale from light (a few) to dark (many; " +
          "the colour bar right of the plot); recomputed for the view when you pan or zoom."})
  const basLegend = h("div", {class: "legend basin-legend"})
  const colourNote = h("div", {class: "legend colour-note", hidden: true})
  const orbStatus = h("div", {class: "orbit-status", "aria-live": "polite"})
  const orbTable = h("div", {class: "orbits", hidden: true})
  // The plot first and large: its key (basins' colours, density) right under it; beside it a column with the k-series
  // and, under them, the orbit table, the layers' statuses and the long legends (scrolled in their box).
  const notes = h("div", {class: "notes"}, orbTable, orbStatus, basStatus, ftleStatus, manStatus, colourNote, eqLegend, orbLegend,
                  manLegend)
  const plotKey = h("div", {class: "plot-key"}, basLegend, densLegend)
  const paneSection = h("section", {class: "pane pane-section"}, secBar, playBar, secErrors, warnings, status,
                        h("div", {class: "plots"}, h("div", {class: "plot-col"}, plotSection, plotKey),
                          h("div", {class: "side-col"}, plotSeries, notes)))

  // Analysis pane (one for every analysis tab; its form is the open tab's controls).
  const aHelp = h("p", {class: "help analysis-help"})
  const aForm = h("div", {class: "form"})
  const runBtn = h("button", {class: "act btn-run", text: "Run"})
  runBtn.addEventListener("click", () => send({action: "run", tab: currentTab}))
  const aStop = h("button", {class: "act warn btn-stop-analysis", text: "Stop"})
  aStop.addEventListener("click", () => send({action: "stop", tab: currentTab}))
  // The open tab's downloads (view.downloads: [what, words, class, ready]), buttons like the section's.
  const aDownloads = h("span", {class: "downloads"})
  const loadBtn = h("button", {class: "act light btn-load-bench", text: "Load latest bench run"})
  loadBtn.addEventListener("click", () => send({action: "load_bench"}))
  const choice = h("select", {class: "bench-choice", "aria-label": "Diagram"})
  choice.addEventListener("change", () => send({action: "bench_choice", value: choice.value}))
  const aFigure = figureBar(send, () => currentTab)
  const aBar = h("div", {class: "bar"}, runBtn, aStop, aDownloads, aFigure, loadBtn, choice)
  const aError = h("div", {class: "error-box analysis-error", role: "alert"})
  const progress = h("progress", {max: 100, hidden: true})
  const aMsg = h("div", {class: "status-line analysis-status", "aria-live": "polite"})
  const aResult = h("div", {class: "result analysis-result"})
  const plotAnalysis = h("div", {class: "plot-analysis"})
  const aLegend = h("div", {class: "legend analysis-legend"})
  const aFoot = h("p", {class: "help analysis-footnote"})
  // The plot takes the pane's height, its key (legend, footnote) under it; the form, Run, the results and the help in
  // a column beside it (scrolled in its box when long: the bifurcations' list).
  const aSide = h("div", {class: "side-col analysis-side"}, aForm, aBar, progress, aMsg, aError, aResult, aHelp)
  const paneAnalysis = h("section", {class: "pane pane-analysis", hidden: true},
                         h("div", {class: "plot-col"}, plotAnalysis, aLegend, aFoot), aSide)
  const main = h("main", {class: "main"}, tourArea, paneSection, paneAnalysis)
  app.append(header, side, main)
  el.append(style, app)

  // Children: the Bokeh figures (the series and analysis ones fill in after the first view).
  const place = (slot, name) => {
    const child = model.get_child(name)
    if (child && child.parentElement !== slot) slot.append(child)
  }
  place(plotSection, "section_plot")
  place(plotAnalysis, "analysis_plot")

  // The section plot gains hover tools when a layer (orbits, manifolds) is first drawn. BokehJS rebuilds the
  // toolbar then without laying the plot out again: the toolbar lands below the page and the legend at the
  // canvas corner (8 of 10 loads). Lay the plot out again after every change of its tools.
  function relayoutOnNewTools(tries = 0) {
    const doc = window.Bokeh && Bokeh.documents && Bokeh.documents[0]
    const fig = doc && doc.get_model_by_name("section_figure")
    if (!fig) {
      if (tries < 600) setTimeout(() => relayoutOnNewTools(tries + 1), 100)
      return
    }
    const views = (v, out) => {
      if (v.model === fig) out.push(v)
      for (const c of v.child_views || []) views(c, out)
      return out
    }
    const relayout = () => requestAnimationFrame(() => {
      for (const root of Object.values(Bokeh.index || {})) for (const v of views(root, [])) v.invalidate_layout()
    })
    fig.toolbar.properties.tools.change.connect(relayout)
    fig.properties.toolbar.change.connect(() => {
      fig.toolbar.properties.tools.change.connect(relayout)
      relayout()
    })
  }
  relayoutOnNewTools()

  // --- the k-series of the selected trajectory: three small SVG charts sharing the k axis -------------
  const SVG = "http://www.w3.org/2000/svg"
  const sv = (tag, attrs, text) => {
    const e = document.createElementNS(SVG, tag)
    for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v)
    if (text !== undefined) e.textContent = text
    return e
  }
  const fmt = (v) => Math.abs(v) >= 1e4 || (Math.abs(v) < 1e-3 && v !== 0) ? v.toExponential(2) : String(+v.toPrecision(4))
  let seriesNote = ""  // why the k-series are empty (the view's words), "" when they show a trajectory
  function drawSeries() {
    const d = model.series || {}
    const ks = d.k || []
    for (const [i, c] of charts.entries()) {
      const W = c.box.clientWidth, H = c.box.clientHeight
      const svg = sv("svg", {viewBox: `0 0 ${Math.max(W, 1)} ${Math.max(H, 1)}`, role: "img",
                             "aria-label": `${c.label} against k`})
      c.box.replaceChildren(svg)
      if (W < 20 || H < 20) continue
      const left = 64, right = 8, top = 6, bottom = i === charts.length - 1 ? 30 : 14
      const ys = d[c.key] || []
      const mid = (top + H - bottom) / 2
      svg.append(sv("text", {x: 12, y: mid, "text-anchor": "middle", transform: `rotate(-90 12 ${mid})`}, c.label))
      if (!ks.length) { svg.append(sv("text", {x: left, y: H / 2}, seriesNote || "no points")); continue }
      const k0 = ks[0], k1 = ks[ks.length - 1] === k0 ? k0 + 1 : ks[ks.length - 1]
      let y0 = Math.min(...ys), y1 = Math.max(...ys)
      if (y1 === y0) { y0 -= 0.5; y1 += 0.5 }
      const X = (k) => left + (k - k0) / (k1 - k0) * (W - left - right)
      const Y = (y) => top + (1 - (y - y0) / (y1 - y0)) * (H - top - bottom)
      svg.append(sv("line", {class: "axis", x1: left, y1: top, x2: left, y2: H - bottom}),
                 sv("line", {class: "axis", x1: left, y1: H - bottom, x2: W - right, y2: H - bottom}),
                 sv("text", {x: left - 4, y: top + 10, "text-anchor": "end"}, fmt(y1)),
                 sv("text", {x: left - 4, y: H - bottom, "text-anchor": "end"}, fmt(y0)))
      if (i === charts.length - 1) {
        svg.append(sv("text", {x: left, y: H - 8}, fmt(k0)),
                   sv("text", {x: W - right, y: H - 8, "text-anchor": "end"}, fmt(k1)),
                   sv("text", {x: (left + W - right) / 2, y: H - 8, "text-anchor": "middle"}, "k"))
      }
      const pts = ks.map((k, j) => `${X(k).toFixed(1)},${Y(ys[j]).toFixed(1)}`).join(" ")
      svg.append(sv("polyline", {points: pts, fill: "none", stroke: c.colour, "stroke-width": 0.8, "stroke-opacity": 0.6}))
      const dots = sv("path", {d: ks.map((k, j) => `M${X(k).toFixed(1)} ${Y(ys[j]).toFixed(1)}h0`).join(""),
                               stroke: c.colour, "stroke-width": 3, "stroke-linecap": "round"})
      svg.append(dots)
    }
  }
  new ResizeObserver(() => drawSeries()).observe(plotSeries)

  // --- state -> page ------------------------------------------------------------------------------
  let currentTab = "section"
  function showTab(t) {
    currentTab = t
    for (const [k, b] of Object.entries(tabButtons)) b.setAttribute("aria-selected", String(k === t))
    paneSection.hidden = t !== "section"
    paneAnalysis.hidden = t === "section"
    if (t !== "section") {
      aForm.replaceChildren(...(byArea[t] || []).map((s) => controls[s.name] ? controls[s.name].wrap : control(s)))
      loadBtn.hidden = choice.hidden = t !== "bench"
      aFigure.hidden = t === "bench"  // its plot is drawn from the bench's files, not a result of the page
      runBtn.textContent = t === "bench" ? "Measure" : "Run"
      runBtn.className = `act btn-run ${t}-run`
    }
    syncValues()
    showView()
  }
  function setPresentation(on) {
    // Presentation mode at 1280x720: the play row's settings (from the link) give their row to the plot; Play and
    // Step join the section's buttons and what plays is said on the status line.
    if (on) {
      secBar.append(playBtn, stepBtn)
    } else {
      playBar.insertBefore(stepBtn, playStatus)
      playBar.insertBefore(playBtn, stepBtn)
    }
    app.classList.toggle("present", on)
    bodyView.setScale(on ? 1.3 : 1)
    app.classList.toggle("side-collapsed", on)
    presentBtn.textContent = on ? "Leave presentation" : "Presentation"
    placeTourChoice()
  }
  function syncValues(force = null) {
    const values = model.values
    // A layer's words under the plot only while the layer is on (a legend of marks not drawn says nothing).
    eqLegend.hidden = !values.show_tracks
    orbLegend.hidden = !values.show_orbits
    const active = el.getRootNode().activeElement
    for (const [name, c] of Object.entries(controls)) {
      if (!(name in values)) continue
      // A box the user is typing in keeps their text until they commit it (Enter or leaving it);
      // the control just committed always shows the value in use (the typed one, or the one kept).
      const typing = (c.inputs || []).some((i) => i === active && i.value !== i.dataset.sent)
      if (!typing || name === force) c.set(values[name])
    }
    noSelBtn.disabled = values.selected === "none"
  }
  function showMessages() {
    for (const [name, c] of Object.entries(controls)) {
      const m = model.messages[name] || ""
      c.msg.textContent = m
      c.wrap.classList.toggle("refused", !!m)
    }
  }
  function lines(box, items) { box.replaceChildren(...items.map((t) => h("div", {text: t}))) }
  function showView() {
    const v = model.view
    const s = v.section || {}
    const pl = s.play || {}
    const playing = pl.playing && pl.frame >= 0 ? `frame ${pl.frame + 1}/${pl.frames}: ${pl.label} = ` +
      `${(+pl.value).toPrecision(5)}, ${pl.fps} frames/s  |  ` : ""
    status.textContent = (app.classList.contains("present") ? playing : "") + (s.status || "")
    status.title = status.textContent
    lines(secErrors, s.errors || [])
    warnings.replaceChildren(...(s.warnings || []).map((w) =>
      h("div", {class: `warn-box level-${w.level} reliability-${w.level}`}, h("b", {text: w.level + ": "}),
        document.createTextNode(w.message))))
    stopBtn.disabled = !s.running
    clearBtn.disabled = !s.n_clicked
    csvBtn.disabled = !s.n_points
    findBtn.disabled = !!s.orbit_view
    findBtn.textContent = s.find_label || "Find orbits in view"
    findBtn.title = s.find_title || ""
    findBtn.setAttribute("aria-pressed", String(!!s.orbit_view))
    clearOrbBtn.disabled = !s.n_orbits && !s.orbit_view && !s.orbit_status
    orbCsvBtn.disabled = !s.n_orbits
    orbStatus.textContent = s.orbit_status || ""
    // Shown only once there are manifolds (or a message about them): the bar stays as short as it was.
    clearManBtn.hidden = !s.n_manifolds && !s.manifold_status
    manCsvBtn.hidden = !s.n_manifolds
    manStatus.textContent = s.manifold_status || ""
    basStatus.textContent = s.basin_status || ""
    basNpzBtn.hidden = !s.basins_file
    ftleStatus.textContent = s.ftle_status || ""
    ftleNpzBtn.hidden = !s.ftle_file
    densLegend.hidden = !s.density
    colourNote.textContent = s.colour_note || ""
    colourNote.hidden = !s.colour_note
    basLegend.replaceChildren(...(s.basin_legend || []).map(([c, t]) =>
      h("span", {class: "basin-item"}, h("span", {class: "sw", style: `background:${c}`}), document.createTextNode(t))))
    const rows = s.orbits || []
    orbTable.hidden = !rows.length
    if (rows.length) {
      const f = (v) => (+v).toPrecision(7)
      const head = h("tr", {}, ...["period", "type", "q", "r", "multipliers"].map((t) => h("th", {text: t})))
      orbTable.replaceChildren(h("table", {class: "orbit-table"}, head, ...rows.map((o) =>
        h("tr", {}, h("td", {text: String(o.period)}), h("td", {text: o.type}), h("td", {text: f(o.q)}),
          h("td", {text: f(o.r)}), h("td", {text: o.mu})))))
    }
    const p = s.play || {}
    playBtn.dataset.playing = p.playing ? "1" : "0"
    playBtn.textContent = p.playing ? "Pause" : "▶ Play"
    playBtn.setAttribute("aria-pressed", String(!!p.playing))
    playStatus.textContent = p.message || (p.frame >= 0 ? `frame ${p.frame + 1}/${p.frames}: ${p.label} = ` +
      `${(+p.value).toPrecision(5)}` + (p.playing ? `, ${p.fps} frames/s` : "") : `${p.label} from ` +
      `${(+p.range[0]).toPrecision(4)} to ${(+p.range[1]).toPrecision(4)} in ${p.frames} frames`)
    if (p.playing && p.number >= 0 && p.number !== lastShown) {
      // This frame's data came before this view (one websocket, in order): drawn at the next paint.
      lastShown = p.number
      requestAnimationFrame(() => send({action: "shown", value: String(p.number)}))
    }
    const tr = s.tour || {}
    const choices = [["", "Guided tour…"], ...(tr.choices || []), [UPLOAD, "Load your own tours file (JSON)…"]]
    if (tourChoice.options.length !== choices.length ||
        choices.some(([v], i) => tourChoice.options[i].value !== v)) {
      tourChoice.replaceChildren(...choices.map(([v, t]) => h("option", {value: v, text: t})))
    }
    tourChoice.value = tourChoice.dataset.shown = tr.id || ""
    tourBox.hidden = !tr.id
    // A tour in presentation mode: the plot gets the room; the bars come back outside it or when a step plays.
    app.classList.toggle("touring", !!tr.id)
    app.classList.toggle("tour-plays", !!tr.plays)
    if (tr.id) {
      tourCount.textContent = `step ${tr.step} of ${tr.steps}`
      tourText.textContent = tr.text
      tourBack.disabled = tr.step <= 1
      tourNext.disabled = tr.step >= tr.steps
    }
    tourMsg.textContent = tr.message || ""
    tourMsg.classList.toggle("problem", !!tr.problem)
    placeTourChoice()
    sceneInfo.textContent = s.scene_info || ""
    const b = s.body || {}
    // The selected trajectory's verdict (regular with its rotation number, chaotic, undecided) after its caption.
    seriesCap.textContent = (b.open ? b.caption : [s.series_caption, s.series_verdict].filter(Boolean).join(" · ")) ||
      ""
    if ((s.series_note || "") !== seriesNote) {
      seriesNote = s.series_note || ""
      requestAnimationFrame(drawSeries)
    }
    bodyView.show(!!b.open)
    if (app.classList.contains("body-open") !== !!b.open) {
      app.classList.toggle("body-open", !!b.open)
      for (const c of charts) c.box.hidden = !!b.open
      if (!b.open) requestAnimationFrame(drawSeries)  // drawn while hidden at no size: again now they show
    }
    if (b.open) bodyView.setStatus(b.status, b.lost)
    if (currentTab !== "section") {
      const a = v[currentTab] || {}
      aHelp.textContent = a.help || ""
      lines(aError, a.errors || [])
      progress.hidden = !(a.running && a.progress !== null && a.progress !== undefined)
      if (!progress.hidden) progress.value = a.progress
      aMsg.textContent = a.running && !a.message ? "computing…" : (a.message || "")
      lines(aResult, a.result || [])
      aStop.disabled = !a.running
      const offered = a.downloads || []
      if (aDownloads.dataset.tab !== currentTab || aDownloads.children.length !== offered.length) {
        aDownloads.dataset.tab = currentTab
        aDownloads.replaceChildren(...offered.map(([what, words, cls]) => {
          const b = h("button", {class: `act light ${cls}`, text: words})
          b.addEventListener("click", () => send({action: "download", what}))
          return b
        }))
      }
      offered.forEach(([, , , ready], i) => { aDownloads.children[i].disabled = !ready })
      aFoot.textContent = a.footnote || ""
      aLegend.replaceChildren()
      if (a.legend) {
        if (a.legend_title) aLegend.append(document.createTextNode(a.legend_title))
        for (const [lab, c] of a.legend) aLegend.append(h("span", {class: "sw", style: `background:${c}`}),
                                                       document.createTextNode(lab))
      }
      if (currentTab === "bench") {
        choice.replaceChildren(...(a.options || []).map((o) => h("option", {value: o, text: o})))
        choice.value = a.choice || ""
        choice.disabled = !(a.options || []).length
      }
    }
  }

  // --- server -> page ---------------------------------------------------------------------------
  model.on("values", syncValues)
  model.on("revision", () => { syncValues(model.committed); showMessages() })
  model.on("messages", showMessages)
  model.on("view", showView)
  model.on("series", drawSeries)
  model.on("body", () => bodyView.setData(model.body))
  model.on("tab", () => { if (model.tab !== currentTab) showTab(model.tab) })
  model.on("presentation", () => setPresentation(model.presentation))
  model.on("msg:custom", (msg) => {
    if (msg && msg.download) {
      const bytes = Uint8Array.from(atob(msg.data), (c) => c.charCodeAt(0))
      const url = URL.createObjectURL(new Blob([bytes], {type: msg.mime}))
      const a = h("a", {href: url, download: msg.download})
      el.append(a)
      a.click()
      a.remove()
      setTimeout(() => URL.revokeObjectURL(url), 10000)
    }
  })
  setPresentation(!!model.presentation)
  if (model.body && model.body.frames) bodyView.setData(model.body)
  showTab(model.tab || "section")
  showMessages()
}
