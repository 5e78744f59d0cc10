// The viewer page's own script (served with the app: `musclewrap.view._app`).
//
// The page's measuring: each slider input gets an id and a time; the server answers
// with the id it drew; two animation frames after the geometry arrives, the picture
// is on screen. One pose at a time is asked for: inputs that come while one is being
// solved wait, the latest replacing the one before, and go when its geometry arrives
// (its drawing then overlaps the next solve). So a drag sends one message a picture,
// not one an input event: 60 a second would keep the server's event loop from the
// solver's results.
(function () {
  const mw = (window.mw = window.mw || { n: 0, t: {}, sent: {}, totals: [], log: [], last: null });
  // A browser that draws in software (Chromium's SwiftShader, Mesa's llvmpipe) takes 2-3 times
  // as long to draw the scene antialiased (BENCHMARKS.md, "The viewer"): there the view's
  // WebGL context is made without (before vtk.js makes it); ?antialias=1 or 0 in the address
  // decides instead. A graphics processor antialiases at little cost: it keeps it.
  if (mw.antialias === undefined) {
    let name = "";
    try {
      const probe = document.createElement("canvas").getContext("webgl");
      const info = probe && probe.getExtension("WEBGL_debug_renderer_info");
      name = probe ? String(probe.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : probe.RENDERER)) : "";
      const lose = probe && probe.getExtension("WEBGL_lose_context");
      if (lose) lose.loseContext();
    } catch (e) { /* no WebGL: vtk.js says so */ }
    const asked = new URLSearchParams(window.location.search).get("antialias");
    mw.renderer = name;
    mw.software = /swiftshader|llvmpipe|softpipe|software/i.test(name);
    mw.antialias = asked === null ? !mw.software : asked !== "0";
    if (!mw.antialias) {
      const make = HTMLCanvasElement.prototype.getContext;
      HTMLCanvasElement.prototype.getContext = function (type, attrs) {
        if (type === "webgl2" || type === "webgl") attrs = Object.assign({}, attrs, { antialias: false });
        return make.call(this, type, attrs);
      };
    }
  }
  const TYPES = { f32: Float32Array, u32: Uint32Array, u8: Uint8Array };
  const views = new WeakMap();
  mw.typed = function (v, kind) {
    if (!(v instanceof Uint8Array)) return v;  // null (nothing yet) or an empty list
    let got = views.get(v);
    if (got === undefined) {
      const T = TYPES[kind], size = T.BYTES_PER_ELEMENT;
      // a view needs its start aligned to its type: a message's bytes may not be
      const b = v.byteOffset % size ? v.slice() : v;
      got = new T(b.buffer, b.byteOffset, b.byteLength / size);
      views.set(v, got);
    }
    return got;
  };
  let inflight = null, pending = null;  // the input being solved (id, time sent), the next
  function send(p) {
    inflight = { id: p.id, at: performance.now() };
    mw.sent[p.id] = inflight.at;
    window.trame.trigger("mw_input", [p.source, p.value, p.id, p.moving]);
  }
  // A slider's input events while it moves ask for poses drawn lighter (the server's
  // `Lighter` surfaces); its change event (let go, a key, a value typed) says that the
  // poses up to the last input are to be drawn in full: the server draws the one it has
  // shown again in full, or a later one in full at once.
  document.addEventListener("input", (e) => {
    const el = e.target;
    if (!el || !el.dataset || !el.dataset.mw || !window.trame) return;
    const id = ++mw.n;
    mw.t[id] = performance.now();
    const p = { source: el.dataset.mw, value: parseFloat(el.value), id, moving: true };
    // a pose asked for more than 3 s ago and not come back (a failed one): ask anyway
    if (inflight && performance.now() - inflight.at < 3000) pending = p; else send(p);
  }, true);
  document.addEventListener("change", (e) => {
    const el = e.target;
    if (!el || !el.dataset || !el.dataset.mw || !window.trame) return;
    window.trame.trigger("mw_still", [mw.n]);
  }, true);
  function median(a) { const s = [...a].sort((x, y) => x - y); return s[Math.floor(s.length / 2)]; }
  function shown(s) {
    if (!s || !s.serial) return;
    const got = performance.now();
    // the pose asked for is here (or another's, which replaced it: play): the next one goes
    if (inflight && (!s.id || s.id >= inflight.id)) {
      inflight = null;
      if (pending) { const p = pending; pending = null; send(p); }
    }
    requestAnimationFrame(() => requestAnimationFrame(() => {
      const drawn = performance.now();
      const t0 = s.id && mw.t[s.id] !== undefined ? mw.t[s.id] : got;
      const sent = s.id && mw.sent[s.id] !== undefined ? mw.sent[s.id] : t0;
      for (const k of Object.keys(mw.t)) if (+k <= s.id) { delete mw.t[k]; delete mw.sent[k]; }
      const total = drawn - t0, render = drawn - got, queued = sent - t0;
      const transfer = Math.max(0, got - sent - s.server);
      mw.totals.push(total); if (mw.totals.length > 10) mw.totals.shift();
      mw.last = { serial: s.serial, id: s.id, total, render, transfer, queued, server: s.server,
                  solve: s.solve, drawn, count: (mw.last ? mw.last.count : 0) + 1 };
      mw.log.push(mw.last);  // the last pictures drawn, for a drag's rate
      if (mw.log.length > 1000) mw.log.shift();
      const el = document.getElementById("mw-update");
      if (el) {
        el.textContent = `update ${total.toFixed(0)} ms (median ${median(mw.totals).toFixed(0)} ms `
          + `of the last ${mw.totals.length}; queued ${queued.toFixed(0)}, solve `
          + `${s.solve.toFixed(0)}, transfer `
          + `${transfer.toFixed(0)}, render ${render.toFixed(0)} ms)`
          + (mw.software ? `; drawn in software, antialiasing ${mw.antialias ? "on" : "off"}` : "");
        el.dataset.serial = String(s.serial);
      }
    }));
  }
  // the server moves a slider's thumb only where the pose comes from elsewhere (a frame:
  // the coordinates' sliders, or play: the time slider); the slider the hand holds is the page's
  function thumbs(t) {
    if (!t || !t.values) return;
    for (const [id, v] of Object.entries(t.values)) {
      const el = document.getElementById(id);
      if (el) el.value = String(v);
    }
  }
  function hook() {
    // (this script runs before the app: wait for the server's state and the page's status line)
    if (!window.trame || !window.trame.state || window.trame.state.get("shown") === undefined
        || !document.getElementById("mw-update")) {
      setTimeout(hook, 50);
      return;
    }
    window.trame.state.watch(["shown"], shown);
    window.trame.state.watch(["thumbs"], thumbs);
    // a pose there before this page came (a page loaded again, or after its first pose)
    thumbs(window.trame.state.get("thumbs"));
    shown(window.trame.state.get("shown"));
    window.trame.trigger("mw_hello");
  }
  hook();
})();
