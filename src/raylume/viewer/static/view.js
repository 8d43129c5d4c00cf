// raylume view: draws the frames the server pushes over a WebSocket and sends the mouse's
// gestures back. Plain JavaScript, no build step, nothing loaded from elsewhere.
"use strict";
(() => {
  const token = new URLSearchParams(location.search).get("token") || "";
  const q = "?token=" + encodeURIComponent(token);
  const canvas = document.getElementById("view");
  const ctx = canvas.getContext("2d");
  const $ = (id) => document.getElementById(id);
  // What tests and the benchmark read: frames received and drawn, the last frame's header.
  const state = (window.raylumeView = {
    received: 0, drawn: 0, denoised: 0, pixels: 0, last: null, drawnFrame: 0, error: null,
  });
  document.getElementById("save").href = "frame.png" + q;

  let socket = null;
  let latestNumber = 0;

  function connect() {
    const scheme = location.protocol === "https:" ? "wss://" : "ws://";
    socket = new WebSocket(scheme + location.host + "/ws" + q);
    socket.binaryType = "arraybuffer";
    socket.onopen = () => setStatus("connected");
    socket.onclose = () => { setStatus("disconnected; retrying...", true); setTimeout(connect, 1000); };
    socket.onmessage = (event) => {
      if (typeof event.data === "string") {
        const msg = JSON.parse(event.data);
        if (msg.error) { state.error = msg.error; setStatus(msg.error, true); }
        return;
      }
      receive(event.data);
    };
  }

  // A frame: uint32 (big-endian) header length, the JSON header, the encoded image.
  async function receive(buffer) {
    const view = new DataView(buffer);
    const n = view.getUint32(0);
    const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, n)));
    const blob = new Blob([new Uint8Array(buffer, 4 + n)], { type: "image/" + header.format });
    state.received += 1;
    latestNumber = Math.max(latestNumber, header.frame);
    const bitmap = await createImageBitmap(blob, { colorSpaceConversion: "none", premultiplyAlpha: "none" });
    if (header.frame < latestNumber) { bitmap.close(); return; }  // a newer frame is already decoding
    if (canvas.width !== header.full_width || canvas.height !== header.full_height) {
      canvas.width = header.full_width;
      canvas.height = header.full_height;
      fit();
    }
    if (bitmap.width === canvas.width && bitmap.height === canvas.height) {
      ctx.drawImage(bitmap, 0, 0);  // 1:1, every pixel as sent
    } else {
      ctx.imageSmoothingEnabled = true;  // a reduced-resolution frame while the camera moves
      ctx.drawImage(bitmap, 0, 0, canvas.width, canvas.height);
    }
    bitmap.close();
    state.drawn += 1;
    if (header.denoised) state.denoised += 1;
    state.pixels += header.width * header.height;
    state.drawnFrame = header.frame;
    state.last = header;
    window.dispatchEvent(new CustomEvent("raylume-frame", { detail: header }));
    $("spp").textContent = header.spp;
    $("fps").textContent = header.fps.toFixed(1);
    $("mrays").textContent = header.mrays_per_second.toFixed(1);
    if ($("mode").value !== header.mode && document.activeElement !== $("mode")) $("mode").value = header.mode;
    showDenoise(header.denoise);
    setStatus(header.converged ? "converged" : header.status);
  }

  // The canvas at its own size in CSS pixels, or smaller to fit the window beside the bar and
  // the help line: never enlarged beyond its pixels (the browser's zoom still enlarges it).
  function fit() {
    const main = document.querySelector("main");
    const style = getComputedStyle(main);
    const gap = parseFloat(style.rowGap) || 0;
    const width = document.documentElement.clientWidth - parseFloat(style.paddingLeft) - parseFloat(style.paddingRight);
    const height = document.documentElement.clientHeight - parseFloat(style.paddingTop) - parseFloat(style.paddingBottom)
      - $("bar").offsetHeight - $("help").offsetHeight - 2 * gap;
    const scale = Math.max(0.05, Math.min(1, width / canvas.width, height / canvas.height));
    canvas.style.width = canvas.width * scale + "px";
    canvas.style.height = canvas.height * scale + "px";
  }
  window.addEventListener("resize", fit);
  fit();

  // The denoise checkbox follows the server (another tab may switch it), except just after a click.
  let denoiseClicked = -Infinity;
  function showDenoise(on) {
    if (typeof on === "boolean" && performance.now() - denoiseClicked > 1500) $("denoise").checked = on;
  }

  function setStatus(text, error) {
    const el = $("status");
    el.textContent = text;
    el.className = error ? "error" : "";
  }

  function send(message) {
    if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(message));
  }
  state.send = send;  // benchmarks/bench_view.py times a gesture from here to its frame

  // Gestures: movements are summed and sent at most once per animation frame.
  let drag = null;
  let pending = { orbit: [0, 0], pan: [0, 0], dolly: 0 };
  let scheduled = false;
  function flush() {
    scheduled = false;
    for (const kind of ["orbit", "pan"]) {
      const [dx, dy] = pending[kind];
      if (dx || dy) send({ type: kind, dx, dy });
    }
    if (pending.dolly) send({ type: "dolly", delta: pending.dolly });
    pending = { orbit: [0, 0], pan: [0, 0], dolly: 0 };
  }
  function schedule() {
    if (!scheduled) { scheduled = true; requestAnimationFrame(flush); }
  }
  canvas.addEventListener("pointerdown", (e) => {
    drag = { x: e.clientX, y: e.clientY, kind: e.button === 2 || e.shiftKey ? "pan" : "orbit" };
    try { canvas.setPointerCapture(e.pointerId); } catch (err) { /* a synthetic event */ }
    canvas.classList.add("dragging");
    e.preventDefault();
  });
  canvas.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const scale = canvas.width / canvas.getBoundingClientRect().width;  // CSS pixels -> image pixels
    pending[drag.kind][0] += (e.clientX - drag.x) * scale;
    pending[drag.kind][1] += (e.clientY - drag.y) * scale;
    drag.x = e.clientX;
    drag.y = e.clientY;
    schedule();
  });
  const end = () => { drag = null; canvas.classList.remove("dragging"); };
  canvas.addEventListener("pointerup", end);
  canvas.addEventListener("pointercancel", end);
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    pending.dolly += e.deltaMode === 1 ? e.deltaY * 33 : e.deltaY;  // lines -> pixels
    schedule();
  }, { passive: false });

  $("reset").addEventListener("click", () => send({ type: "reset" }));
  $("mode").addEventListener("change", (e) => send({ type: "mode", mode: e.target.value }));
  $("denoise").addEventListener("change", (e) => {
    denoiseClicked = performance.now();
    send({ type: "denoise", on: e.target.checked });
  });

  // fps falls to 0 once the image has converged and no frames come: poll /stats for it.
  setInterval(async () => {
    try {
      const stats = await (await fetch("stats" + q)).json();
      $("fps").textContent = stats.fps.toFixed(1);
      $("mrays").textContent = stats.mrays_per_second.toFixed(1);
      showDenoise(stats.denoise);
      if (stats.error) setStatus(stats.error, true);
      else if (!stats.frames) setStatus(stats.status);
    } catch (err) { /* the server is gone: the socket's retry says so */ }
  }, 1000);

  connect();
})();
