// report.js: the behaviour of report.html (outputs/assets/report.html). Plain ES5-style
// script, no modules (file:// pages cannot import them), three.js r111 globals (THREE).
//
// One clock: `state.t` in seconds, set by the player, the slider, a click on a plot or the
// page's address (#t=1.5). Every view reads it: the mesh (the glb's morph-weight animation
// through THREE.AnimationMixer), the plots' cursor and the readouts.
//
// Address options: #t=1.5 opens at 1.5 s; #regions colours the surface by anatomical region;
// #t=1.5&regions both. Test hook: report.html#selftest=T1,T2 renders the lung at T1 and T2, reads the WebGL canvas
// back and writes one JSON line into the page's #selftest element (see docs/formats.md).
(function () {
  'use strict';

  // ---- errors are counted for the self-test (and still reported to the console) ----
  var errors = [];
  window.addEventListener('error', function (e) { errors.push(String(e.message || e)); });
  window.addEventListener('unhandledrejection', function (e) { errors.push('unhandled rejection: ' + String(e.reason)); });
  var consoleError = console.error;
  console.error = function () {
    errors.push(Array.prototype.map.call(arguments, String).join(' '));
    consoleError.apply(console, arguments);
  };

  var data = JSON.parse(document.getElementById('pneuma-data').textContent);
  var REGION_COLORS = { apex: '#4c78a8', costal: '#f58518', diaphragmatic: '#54a24b', mediastinal: '#b279a2' };
  var PALETTE = ['#c4524d', '#4c78a8', '#54a24b', '#b279a2', '#f58518', '#72b7b2'];
  var duration = data.duration_s;
  var frameStep = data.frame_rate_hz > 0 ? 1 / data.frame_rate_hz : duration / 100;

  var state = { t: 0, playing: false, speed: 1 };
  var listeners = [];
  function seek(t) {
    if (!(t >= 0)) t = 0;
    if (t > duration) t = duration;
    state.t = t;
    for (var i = 0; i < listeners.length; ++i) listeners[i](t);
  }

  // ---- small helpers ----
  function el(tag, attrs, text) {
    var e = document.createElement(tag);
    if (attrs) for (var k in attrs) e.setAttribute(k, attrs[k]);
    if (text !== undefined) e.textContent = text;
    return e;
  }
  function fmt(x, digits) {
    if (x === null || x === undefined || isNaN(x)) return '-';
    var text = Number(x).toFixed(digits);
    return /^-0(\.0*)?$/.test(text) ? text.slice(1) : text;  // no "-0.00"
  }
  function base64ToBytes(text) {
    var raw = atob(text.replace(/\s+/g, ''));
    var bytes = new Uint8Array(raw.length);
    for (var i = 0; i < raw.length; ++i) bytes[i] = raw.charCodeAt(i);
    return bytes;
  }
  // Index of the last sample at or before t (times ascending).
  function lowerIndex(times, t) {
    var lo = 0, hi = times.length - 1;
    if (t <= times[0]) return 0;
    if (t >= times[hi]) return hi;
    while (hi - lo > 1) {
      var mid = (lo + hi) >> 1;
      if (times[mid] <= t) lo = mid; else hi = mid;
    }
    return lo;
  }
  function valueAt(times, values, t) {
    var i = lowerIndex(times, t);
    if (i >= times.length - 1) return values[times.length - 1];
    var a = times[i], b = times[i + 1];
    var w = b > a ? Math.min(Math.max((t - a) / (b - a), 0), 1) : 0;
    return values[i] + w * (values[i + 1] - values[i]);
  }
  function niceStep(range, count) {
    var raw = range / Math.max(count, 1);
    var mag = Math.pow(10, Math.floor(Math.log10(raw)));
    var n = raw / mag;
    return (n < 1.5 ? 1 : n < 3 ? 2 : n < 7 ? 5 : 10) * mag;
  }

  // ---- header, facts, motion table ----
  document.getElementById('description').textContent = data.description || '';
  (function facts() {
    var table = document.getElementById('facts');
    data.facts.forEach(function (f) {
      var tr = el('tr');
      tr.appendChild(el('td', null, f[0]));
      tr.appendChild(el('td', null, f[1]));
      table.appendChild(tr);
    });
  })();
  (function motion() {
    var table = document.getElementById('motion');
    var note = document.getElementById('motion-note');
    var m = data.motion;
    if (!m || !m.breaths) {
      note.textContent = 'No complete breath in this run: no per-region motion to show.';
      return;
    }
    var columns = [
      ['area_cm2', 'area (cm\u00b2)', 1], ['caudal_mean_mm', 'caudal mean (mm)', 2],
      ['anterior_mean_mm', 'anterior mean (mm)', 2], ['lateral_mean_mm', 'lateral mean (mm)', 2],
      ['magnitude_mean_mm', '|d| mean (mm)', 2], ['magnitude_max_mm', '|d| peak (mm)', 2],
      ['volume_share_pct', 'share of \u0394V (%)', 1]];
    var byLung = m.regions.some(function (r) { return r.lung; });  // two lungs: a row per lung and region
    var head = el('tr');
    if (byLung) head.appendChild(el('th', null, 'lung'));
    head.appendChild(el('th', null, 'region'));
    columns.forEach(function (c) { head.appendChild(el('th', null, c[1])); });
    table.appendChild(head);
    m.regions.forEach(function (r) {
      var tr = el('tr');
      if (byLung) tr.appendChild(el('td', null, r.lung));
      var name = el('td');
      var swatch = el('span', { 'class': 'swatch' });
      swatch.style.background = REGION_COLORS[r.name] || '#999';
      name.appendChild(swatch);
      name.appendChild(document.createTextNode(r.name));
      tr.appendChild(name);
      columns.forEach(function (c) { tr.appendChild(el('td', null, fmt(r[c[0]], c[2]))); });
      table.appendChild(tr);
    });
    var dome = byLung
        ? Object.keys(m.dome_top_caudal_mm_by_lung).map(function (k) {
            return k + ' ' + fmt(m.dome_top_caudal_mm_by_lung[k], 2) + ' mm';
          }).join(', ') + ' caudal. '
        : fmt(m.dome_top_caudal_mm, 2) + ' mm caudal. ';
    note.textContent = 'Mean over ' + m.breaths + ' complete breath' + (m.breaths === 1 ? '' : 's') +
        ': the displacement from each breath\'s lowest to its highest volume, in body axes (caudal: downward; ' +
        'lateral: away from the midline). Dome top: ' + dome + 'Per breath: motion.csv.';
  })();

  // ---- plots: each a <canvas>, its static part drawn once per size, the cursor per frame ----
  var series = data.series;
  var times = series.columns.time_s;
  // spec: {title, unit, columns} of the physiology series, or with its own {times, values, labels}
  // (the points' trajectories).
  function Plot(spec, index) {
    var self = this;
    this.spec = spec;
    this.times = spec.times || times;
    this.root = el('div', { 'class': 'plot' });
    var head = el('div', { 'class': 'head' });
    var title = el('b', null, spec.title + ' (' + spec.unit + ')');
    head.appendChild(title);
    this.readouts = [];
    this.lines = spec.columns.map(function (key, j) {
      var color = PALETTE[(index === 0 ? j : j) % PALETTE.length];
      var keyEl = el('span', { 'class': 'key' });
      var swatch = el('i');
      swatch.style.background = color;
      keyEl.appendChild(swatch);
      keyEl.appendChild(document.createTextNode((spec.labels || series.labels)[key] + ' '));
      var readout = el('span', null, '');
      keyEl.appendChild(readout);
      head.appendChild(keyEl);
      self.readouts.push(readout);
      return { key: key, values: (spec.values || series.columns)[key], color: color };
    });
    this.canvas = el('canvas', { 'aria-label': spec.title });
    this.root.appendChild(head);
    this.root.appendChild(this.canvas);
    this.cache = document.createElement('canvas');
    var lo = Infinity, hi = -Infinity;
    this.lines.forEach(function (l) {
      for (var i = 0; i < l.values.length; ++i) { lo = Math.min(lo, l.values[i]); hi = Math.max(hi, l.values[i]); }
    });
    if (!(hi > lo)) { lo -= 1; hi += 1; }
    var pad = 0.06 * (hi - lo);
    this.y0 = lo - pad; this.y1 = hi + pad;
    var drag = false;
    function seekAt(e) {
      var r = self.canvas.getBoundingClientRect();
      var x = (e.clientX - r.left) * (self.canvas.width / r.width);
      seek(self.tAt(x));
    }
    this.canvas.addEventListener('pointerdown', function (e) { drag = true; self.canvas.setPointerCapture(e.pointerId); seekAt(e); });
    this.canvas.addEventListener('pointermove', function (e) { if (drag) seekAt(e); });
    this.canvas.addEventListener('pointerup', function () { drag = false; });
  }
  Plot.prototype.layout = function () {
    var dpr = window.devicePixelRatio || 1;
    var w = Math.max(1, Math.round(this.canvas.clientWidth * dpr)), h = Math.max(1, Math.round(this.canvas.clientHeight * dpr));
    this.canvas.width = w; this.canvas.height = h;
    this.cache.width = w; this.cache.height = h;
    this.dpr = dpr;
    this.left = 46 * dpr; this.right = w - 8 * dpr; this.top = 6 * dpr; this.bottom = h - 18 * dpr;
    this.drawStatic();
  };
  Plot.prototype.xAt = function (t) { return this.left + (this.right - this.left) * (duration > 0 ? t / duration : 0); };
  Plot.prototype.yAt = function (v) { return this.bottom - (this.bottom - this.top) * (v - this.y0) / (this.y1 - this.y0); };
  Plot.prototype.tAt = function (x) { return (x - this.left) / (this.right - this.left) * duration; };
  Plot.prototype.drawStatic = function () {
    var g = this.cache.getContext('2d'), dpr = this.dpr, self = this;
    g.clearRect(0, 0, this.cache.width, this.cache.height);
    g.font = (11 * dpr) + 'px system-ui, sans-serif';
    g.strokeStyle = '#e3e6ea'; g.fillStyle = '#5d6773'; g.lineWidth = 1;
    var ys = niceStep(this.y1 - this.y0, 3);
    g.textAlign = 'right'; g.textBaseline = 'middle';
    for (var v = Math.ceil(this.y0 / ys) * ys; v <= this.y1; v += ys) {
      var y = Math.round(this.yAt(v)) + 0.5;
      g.beginPath(); g.moveTo(this.left, y); g.lineTo(this.right, y); g.stroke();
      g.fillText(Math.abs(v) < ys * 1e-6 ? '0' : String(+v.toPrecision(6)), this.left - 4 * dpr, y);
    }
    var xs = niceStep(duration || 1, Math.max(2, Math.floor((this.right - this.left) / (70 * dpr))));
    g.textAlign = 'center'; g.textBaseline = 'top';
    for (var t = 0; t <= duration + 1e-9; t += xs) {
      var x = Math.round(this.xAt(t)) + 0.5;
      g.beginPath(); g.moveTo(x, this.top); g.lineTo(x, this.bottom); g.stroke();
      g.textAlign = x > this.right - 20 * dpr ? 'right' : 'center';
      g.fillText(+t.toPrecision(6) + ' s', Math.min(x, this.right), this.bottom + 3 * dpr);
    }
    if (this.bands) this.bands(g);
    if (this.marks) this.marks(g);
    g.lineWidth = 1.5 * dpr; g.lineJoin = 'round';
    this.lines.forEach(function (l) {
      g.strokeStyle = l.color;
      g.beginPath();
      for (var i = 0; i < self.times.length; ++i) {
        var px = self.xAt(self.times[i]), py = self.yAt(l.values[i]);
        if (i === 0) g.moveTo(px, py); else g.lineTo(px, py);
      }
      g.stroke();
    });
  };
  Plot.prototype.drawCursor = function (t) {
    var g = this.canvas.getContext('2d'), dpr = this.dpr, self = this;
    g.clearRect(0, 0, this.canvas.width, this.canvas.height);
    g.drawImage(this.cache, 0, 0);
    var x = Math.round(this.xAt(t)) + 0.5;
    g.strokeStyle = '#1d232b'; g.lineWidth = 1 * dpr;
    g.beginPath(); g.moveTo(x, this.top); g.lineTo(x, this.bottom); g.stroke();
    this.lines.forEach(function (l, j) {
      var v = valueAt(self.times, l.values, t);
      g.fillStyle = l.color;
      g.beginPath(); g.arc(x, self.yAt(v), 3 * dpr, 0, 2 * Math.PI); g.fill();
      self.readouts[j].textContent = fmt(v, Math.abs(v) >= 100 ? 0 : 2);
    });
  };

  var plotsRoot = document.getElementById('plots');
  var plots = data.plots.map(function (spec, i) {
    var p = new Plot(spec, i);
    plotsRoot.appendChild(p.root);
    return p;
  });
  // ---- points that follow the breath (voxels.points): each one's displacement from rest ----
  var TRACK_COLORS = ['#ff2fd0', '#00e5ff', '#ffe600', '#ff6a00', '#7cff4f', '#ffffff'];
  var STRUCTURE_COLORS = ['#ff1f1f', '#21ff74', '#a020ff'], ITV_COLORS = ['#ff9d9d', '#b3ffd1', '#d9a6ff'];
  var tracks = data.trajectories || null;
  if (tracks) {
    tracks.points.forEach(function (p, k) {
      // LPS: x to the patient's left, y posterior, z superior; the change from the CSV's rest position.
      var values = { lr: [], ap: [], si: [] };
      for (var f = 0; f < tracks.times_s.length; ++f) {
        values.lr.push(p.x_mm[f] - p.rest_mm[0]);
        values.ap.push(p.y_mm[f] - p.rest_mm[1]);
        values.si.push(p.z_mm[f] - p.rest_mm[2]);
      }
      var plot = new Plot({ title: 'Point ' + p.name + ' (' + p.moves_with + ', marker ' + (k + 1) +
                                   ' on the slices) from rest, LPS', unit: 'mm', columns: ['lr', 'ap', 'si'],
                            times: tracks.times_s, values: values,
                            labels: { lr: 'LR (x, +left)', ap: 'AP (y, +posterior)', si: 'SI (z, +superior)' } }, k);
      plot.root.setAttribute('data-point', p.name);
      plotsRoot.appendChild(plot.root);
      plots.push(plot);
    });
  }
  // ---- the ventilator screen (ventilated runs): the numerics of the breath under the cursor ----
  var SCREEN = [['pip', 'PIP', 'cmH2O', 1], ['pplat', 'Pplat', 'cmH2O', 1], ['pmean', 'Pmean', 'cmH2O', 1],
                ['peep', 'PEEP', 'cmH2O', 1], ['peepi', 'PEEPi', 'cmH2O', 1], ['vti', 'VTi', 'mL', 0],
                ['vte', 'VTe', 'mL', 0], ['mve', 'MVe', 'L/min', 2], ['rr', 'RR', '/min', 1],
                ['rr_spont', 'RRspon', '/min', 1], ['ie', 'I:E', '', 2], ['cdyn', 'Cdyn', 'mL/cmH2O', 1],
                ['leak', '% leak', '%', 0]];
  var screen = null;
  function Screen(breaths, starts) {
    var self = this;
    this.breaths = breaths; this.starts = starts;
    this.root = el('div', { 'class': 'screen', 'id': 'ventilator-screen' });
    this.title = el('div', { 'class': 'head' }, 'Ventilator');
    this.root.appendChild(this.title);
    var grid = el('div', { 'class': 'cells' });
    this.root.appendChild(grid);
    this.cells = {};
    SCREEN.forEach(function (c) {
      var cell = el('div', { 'class': 'cell' });
      cell.appendChild(el('span', { 'class': 'name' }, c[1] + (c[2] ? ' ' + c[2] : '')));
      var value = el('b', { 'data-key': c[0] }, '-');
      cell.appendChild(value);
      grid.appendChild(cell);
      self.cells[c[0]] = value;
    });
    this.alarms = el('div', { 'class': 'alarms' }, '');
    this.root.appendChild(this.alarms);
    this.shown = null;
  }
  // The breath holding t: [starts[b], starts[b + 1]); -1 before the first or after the last.
  Screen.prototype.show = function (t) {
    var b = -1, self = this;
    for (var i = 0; i + 1 < this.starts.length; ++i) if (this.starts[i] <= t && t < this.starts[i + 1]) b = i;
    var breath = b >= 0 ? this.breaths[b] : null;
    this.title.textContent = breath ? 'Ventilator: breath ' + (b + 1) : 'Ventilator';
    var shown = { breath: b + 1, values: {}, alarms: breath ? breath.alarms : '' };
    SCREEN.forEach(function (c) {
      var v = breath ? breath[c[0]] : null;
      var text = v === null || v === undefined ? '-' : (c[0] === 'ie' ? '1:' + fmt(v, c[3]) : fmt(v, c[3]));
      self.cells[c[0]].textContent = text;
      shown.values[c[0]] = text;
    });
    this.alarms.textContent = breath && breath.alarms ? 'Alarms: ' + breath.alarms.split(';').join(', ') : '';
    this.shown = shown;
  };

  // ---- loops (ventilated runs): pressure-volume and flow-volume of the breath under the cursor ----
  function Loop(title, xKey, xUnit, yKey, yUnit, starts) {
    var self = this;
    this.xs = series.columns[xKey]; this.ys = series.columns[yKey]; this.starts = starts;
    this.root = el('div', { 'class': 'loop' });
    this.root.appendChild(el('div', { 'class': 'head' }, title));
    this.canvas = el('canvas', { 'aria-label': title });
    this.root.appendChild(this.canvas);
    function range(v) {
      var lo = Infinity, hi = -Infinity;
      for (var i = 0; i < v.length; ++i) { lo = Math.min(lo, v[i]); hi = Math.max(hi, v[i]); }
      if (!(hi > lo)) { lo -= 1; hi += 1; }
      var pad = 0.06 * (hi - lo);
      return [lo - pad, hi + pad];
    }
    this.xr = range(this.xs); this.yr = range(this.ys);
    this.xUnit = xUnit; this.yUnit = yUnit;
  }
  Loop.prototype.layout = function () {
    var dpr = window.devicePixelRatio || 1;
    this.canvas.width = Math.max(1, Math.round(this.canvas.clientWidth * dpr));
    this.canvas.height = Math.max(1, Math.round(this.canvas.clientHeight * dpr));
    this.dpr = dpr;
    this.left = 46 * dpr; this.right = this.canvas.width - 8 * dpr; this.top = 6 * dpr; this.bottom = this.canvas.height - 18 * dpr;
  };
  Loop.prototype.px = function (v) { return this.left + (this.right - this.left) * (v - this.xr[0]) / (this.xr[1] - this.xr[0]); };
  Loop.prototype.py = function (v) { return this.bottom - (this.bottom - this.top) * (v - this.yr[0]) / (this.yr[1] - this.yr[0]); };
  Loop.prototype.draw = function (t) {
    var g = this.canvas.getContext('2d'), dpr = this.dpr, self = this;
    g.clearRect(0, 0, this.canvas.width, this.canvas.height);
    g.font = (11 * dpr) + 'px system-ui, sans-serif';
    g.strokeStyle = '#e3e6ea'; g.fillStyle = '#5d6773'; g.lineWidth = 1;
    var ys = niceStep(this.yr[1] - this.yr[0], 3), xs = niceStep(this.xr[1] - this.xr[0], 4), v, p;
    g.textAlign = 'right'; g.textBaseline = 'middle';
    for (v = Math.ceil(this.yr[0] / ys) * ys; v <= this.yr[1]; v += ys) {
      p = Math.round(this.py(v)) + 0.5;
      g.beginPath(); g.moveTo(this.left, p); g.lineTo(this.right, p); g.stroke();
      g.fillText(Math.abs(v) < ys * 1e-6 ? '0' : String(+v.toPrecision(6)), this.left - 4 * dpr, p);
    }
    g.textAlign = 'center'; g.textBaseline = 'top';
    for (v = Math.ceil(this.xr[0] / xs) * xs; v <= this.xr[1]; v += xs) {
      p = Math.round(this.px(v)) + 0.5;
      g.beginPath(); g.moveTo(p, this.top); g.lineTo(p, this.bottom); g.stroke();
      g.fillText((Math.abs(v) < xs * 1e-6 ? '0' : String(+v.toPrecision(6))) + ' ' + this.xUnit, p, this.bottom + 3 * dpr);
    }
    // The breath holding t: [starts[b], starts[b + 1]); none before the first or after the last.
    var b = -1;
    for (var i = 0; i + 1 < this.starts.length; ++i) if (this.starts[i] <= t && t < this.starts[i + 1]) b = i;
    if (b < 0) return;
    var t0 = this.starts[b], t1 = this.starts[b + 1];
    function path(until, color, width) {
      g.strokeStyle = color; g.lineWidth = width * dpr; g.lineJoin = 'round';
      g.beginPath();
      var first = true;
      for (var k = 0; k < times.length; ++k) {
        if (times[k] < t0 || times[k] > until) continue;
        var x = self.px(self.xs[k]), y = self.py(self.ys[k]);
        if (first) { g.moveTo(x, y); first = false; } else g.lineTo(x, y);
      }
      g.stroke();
    }
    path(t1, '#c9ced6', 1.2);      // the whole breath
    path(t, PALETTE[1], 1.8);      // so far
    g.fillStyle = '#1d232b';
    g.beginPath(); g.arc(this.px(valueAt(times, this.xs, t)), this.py(valueAt(times, this.ys, t)), 3 * dpr, 0, 2 * Math.PI); g.fill();
  };
  if (data.loops) {
    var loopsRoot = el('div', { 'class': 'loops' });
    plotsRoot.appendChild(loopsRoot);
    var starts = data.loops.breath_starts;
    var loops = [new Loop('Pressure-volume loop: volume (mL) against airway pressure', 'airway_pressure_cmH2O', 'cmH2O', 'volume_mL', 'mL', starts),
                 new Loop('Flow-volume loop: flow (L/s) against volume', 'volume_mL', 'mL', 'flow_L_per_s', 'L/s', starts)];
    loops.forEach(function (l) { loopsRoot.appendChild(l.root); plots.push({
      layout: function () { l.layout(); }, drawCursor: function (t) { l.draw(t); } }); });
    if (data.loops.screen) {
      screen = new Screen(data.loops.screen, starts);
      plotsRoot.appendChild(screen.root);  // a row under the loops
      plots.push({ layout: function () {}, drawCursor: function (t) { screen.show(t); } });
      // Alarms on the time line: a red tick at the end of each breath that raised one (when the
      // ventilator checks it), over every waveform.
      plots.forEach(function (p) {
        if (!p.lines) return;
        p.marks = function (g) {
          g.fillStyle = '#d62728';
          data.loops.screen.forEach(function (b, i) {
            if (!b.alarms) return;
            var x = p.xAt(starts[i + 1]);
            g.fillRect(x - 1.5 * p.dpr, p.top, 3 * p.dpr, 7 * p.dpr);
          });
        };
      });
    }
  }
  // ---- respiratory bins: bands on the volume plot, the table, the bin under the cursor ----
  var bins = data.bins || null;
  function binColor(b, alpha) { return 'hsla(' + Math.round(b * 360 / bins.bins.length) + ',70%,55%,' + alpha + ')'; }
  function binAt(t) {
    if (!bins) return -1;
    var k = Math.min(bins.bin_of_frame.length - 1, Math.max(0, Math.round(t * data.frame_rate_hz)));
    return bins.bin_of_frame[k];
  }
  if (bins && plots.length > 0) {
    var volumePlot = plots[0];
    volumePlot.bands = function (g) {  // each stretch of frames in one bin, half a frame either side
      var of = bins.bin_of_frame, start = 0;
      for (var k = 1; k <= of.length; ++k) {
        if (k < of.length && of[k] === of[start]) continue;
        if (of[start] >= 0) {
          var x0 = volumePlot.xAt(Math.max(0, (start - 0.5) * frameStep));
          var x1 = volumePlot.xAt(Math.min(duration, (k - 0.5) * frameStep));
          g.fillStyle = binColor(of[start], 0.22);
          g.fillRect(x0, volumePlot.top, x1 - x0, volumePlot.bottom - volumePlot.top);
        }
        start = k;
      }
    };
    document.getElementById('bins-panel').hidden = false;
    var binTable = document.getElementById('bins');
    var head = el('tr');
    ['bin', bins.method + ' (%)', 'frames', 'mean volume (mL)'].forEach(function (c) { head.appendChild(el('th', null, c)); });
    binTable.appendChild(head);
    var binRows = bins.bins.map(function (b, i) {
      var tr = el('tr');
      var first = el('td');
      var sw = el('span', { 'class': 'swatch' });
      sw.style.background = binColor(i, 0.6);
      first.appendChild(sw);
      first.appendChild(document.createTextNode(String(i)));
      tr.appendChild(first);
      tr.appendChild(el('td', null, fmt(b.percent, 0)));
      tr.appendChild(el('td', null, String(b.frames)));
      tr.appendChild(el('td', null, fmt(b.mean_volume_mL, 1)));
      binTable.appendChild(tr);
      return tr;
    });
    document.getElementById('bins-note').textContent = '0 % is end-inspiration (as Varian RPM marks it); the ' +
      'bands on the volume plot are the frames of each bin (phases.csv).';
    listeners.push(function (t) {
      var b = binAt(t);
      binRows.forEach(function (tr, i) { tr.className = i === b ? 'current' : ''; });
    });
  }

  // ---- slices of the warped label map (voxel outputs), the time point nearest the cursor ----
  var LUNG_COLORS = ['#e8a33d', '#4c9be8', '#6cc16c', '#d0729c', '#b9a2e8', '#e86a5a', '#5ad0c8'];
  var slices = data.slices || null;
  var slicePlanes = [];
  if (slices) {
    var slicesRoot = document.getElementById('slices');
    slicesRoot.hidden = false;
    var lungIndex = {};
    slices.lung_labels.forEach(function (v, i) { lungIndex[v] = i; });
    slices.planes.forEach(function (plane) {
      var root = el('div', { 'class': 'slice' });
      var headEl = el('div', { 'class': 'head' });
      headEl.appendChild(el('b', null, plane.name.charAt(0).toUpperCase() + plane.name.slice(1)));
      var info = el('span', null, '');
      headEl.appendChild(document.createTextNode(' warped label map, ' + plane.fixed + ' (LPS), ' + fmt(plane.pixel_mm, 1) +
        ' mm pixels' + (plane.name === 'coronal' ? ', patient right on the left' : ', anterior on the left') + '; '));
      headEl.appendChild(info);
      var canvas = el('canvas', { width: String(plane.width), height: String(plane.height), 'aria-label': plane.name + ' slice' });
      canvas.style.aspectRatio = plane.width + ' / ' + plane.height;
      root.appendChild(headEl);
      var row = el('div', { 'class': 'slice-row' });
      row.appendChild(canvas);
      root.appendChild(row);
      slicesRoot.appendChild(root);
      // Beside the labels: the warped CT (when given), |forward DVF| and the Jacobian, as bytes
      // on each channel's scale (report.h: LabelSlice::Channel).
      var channels = (plane.channels || []).map(function (c) {
        var box = el('figure', { 'class': 'channel' });
        var cv = el('canvas', { width: String(plane.width), height: String(plane.height), 'aria-label': plane.name + ' ' + c.name });
        cv.style.aspectRatio = plane.width + ' / ' + plane.height;
        box.appendChild(cv);
        box.appendChild(el('figcaption', null, channelCaption(c)));
        row.appendChild(box);
        var decodedImages = c.images.map(function (b64) {
          var bytes = base64ToBytes(b64), img = new ImageData(plane.width, plane.height), px = img.data;
          for (var k = 0; k < bytes.length; ++k) {
            var rgb = channelColor(c, bytes[k]);
            px[4 * k] = rgb[0]; px[4 * k + 1] = rgb[1]; px[4 * k + 2] = rgb[2]; px[4 * k + 3] = 255;
          }
          return img;
        });
        return { channel: c, canvas: cv, images: decodedImages, shown: -1 };
      });
      // Decoded once each: RGBA pixels, the lung pixel count and the lowest row with lung.
      var decoded = plane.labels.map(function (runs) {
        var img = new ImageData(plane.width, plane.height), px = img.data, at = 0, lung = 0, lowest = -1;
        for (var r = 0; r < runs.length; r += 2) {
          var label = runs[r], n = runs[r + 1], li = lungIndex[label];
          var c = label === 0 ? [32, 36, 40] : li === undefined ? [120, 120, 120] : hexRgb(LUNG_COLORS[li % LUNG_COLORS.length]);
          for (var j = 0; j < n; ++j, ++at) {
            px[4 * at] = c[0]; px[4 * at + 1] = c[1]; px[4 * at + 2] = c[2]; px[4 * at + 3] = 255;
          }
          if (li !== undefined) { lung += n; lowest = Math.floor((at - 1) / plane.width); }
        }
        return { image: img, lung: lung, lowest: lowest };
      });
      // The reference line: the lungs' lowest row at the time point with the least lung (end-expiration).
      var least = 0;
      decoded.forEach(function (d, i) { if (d.lung < decoded[least].lung) least = i; });
      // Each structure's outline pixels (in the mask, a 4-neighbour out of it or off the plane), per time and of its ITV.
      var outlines = (plane.structures || []).map(function (st) {
        return { name: st.name, masks: st.masks.map(function (runs) { return outlinePixels(plane, runs); }),
                 itv: st.itv ? outlinePixels(plane, st.itv) : [] };
      });
      slicePlanes.push({ plane: plane, canvas: canvas, info: info, decoded: decoded, reference: decoded[least].lowest,
                         reference_time: plane.times_s[least], shown: -1, channels: channels, outlines: outlines });
    });
    listeners.push(function (t) { slicePlanes.forEach(function (s) { drawSlice(s, t); }); });
    // The structures (voxels.structures): structures.csv's volume and centroid per time point, the
    // one nearest the cursor marked, and structures-summary.csv's ITV and mid-ventilation.
    (data.structures || []).forEach(function (st) {
      var table = el('table', { 'class': 'voxel-points structure' });
      var mid = st.midventilation === null ? 'none' : st.midventilation + ' at (' + st.midventilation_mm.map(function (v) { return fmt(v, 1); }).join(', ') + ') mm';
      table.appendChild(el('caption', null, 'Structure ' + st.name + ' (outlined on the slices at the time shown, its ITV ' +
        'in a lighter shade of the same colour; voxels/structures.csv): ITV ' +
        (st.itv_mL === null ? 'none' : fmt(st.itv_mL, 2) + ' mL') + ', mid-ventilation ' + mid));
      var head = el('tr');
      ['time point', 't (s)', 'volume (mL)', 'centroid x, y, z (mm, LPS)', 'weight'].forEach(function (h) { head.appendChild(el('th', null, h)); });
      table.appendChild(head);
      var rows = st.rows.map(function (r) {
        var tr = el('tr');
        [r.tag + (r.tag === st.midventilation ? ' (mid-ventilation)' : ''), r.time_s === null ? 'bin' : fmt(r.time_s, 2), fmt(r.volume_mL, 2),
         r.centroid_mm === null ? 'empty' : r.centroid_mm.map(function (v) { return fmt(v, 1); }).join(', '), fmt(r.weight, 3)]
          .forEach(function (v) { tr.appendChild(el('td', null, v)); });
        table.appendChild(tr);
        return tr;
      });
      slicesRoot.appendChild(table);
      listeners.push(function (t) {
        var best = -1;
        st.rows.forEach(function (r, i) {
          if (r.time_s !== null && (best < 0 || Math.abs(r.time_s - t) < Math.abs(st.rows[best].time_s - t))) best = i;
        });
        rows.forEach(function (tr, i) { tr.className = i === best ? 'current' : ''; });
      });
    });
    // The voxel time points' figures (voxels.csv), the one nearest the cursor marked.
    var points = data.voxel_points || [];
    if (points.length) {
      var table = el('table', { 'class': 'voxel-points' });
      table.appendChild(el('caption', null, 'Voxel time points (voxels/voxels.csv): the warped lungs\' volume against ' +
        'the physiology\'s, and the forward map\'s smallest Jacobian inside the lungs'));
      var head = el('tr');
      ['time point', 't (s)', 'volume error', 'smallest J', 'folded tets'].forEach(function (h) { head.appendChild(el('th', null, h)); });
      table.appendChild(head);
      var pointRows = points.map(function (p) {
        var tr = el('tr');
        [p.tag, p.time_s === null ? 'bin' : fmt(p.time_s, 2), fmt(p.volume_error_percent, 2) + ' %', fmt(p.min_jacobian, 3),
         String(p.folded_tets)].forEach(function (v) { tr.appendChild(el('td', null, v)); });
        table.appendChild(tr);
        return tr;
      });
      slicesRoot.appendChild(table);
      listeners.push(function (t) {
        var best = -1;
        points.forEach(function (p, i) {
          if (p.time_s !== null && (best < 0 || Math.abs(p.time_s - t) < Math.abs(points[best].time_s - t))) best = i;
        });
        pointRows.forEach(function (tr, i) { tr.className = i === best ? 'current' : ''; });
      });
    }
  }
  // A 0/1 mask (run lengths) to the indices of its outline pixels.
  function outlinePixels(plane, runs) {
    var w = plane.width, h = plane.height, m = new Uint8Array(w * h), at = 0, out = [];
    for (var r = 0; r < runs.length; r += 2) { if (runs[r]) m.fill(1, at, at + runs[r + 1]); at += runs[r + 1]; }
    for (var i = 0; i < m.length; ++i) {
      if (!m[i]) continue;
      var c = i % w, row = (i - c) / w;
      if (c === 0 || c === w - 1 || row === 0 || row === h - 1 || !m[i - 1] || !m[i + 1] || !m[i - w] || !m[i + w]) out.push(i);
    }
    return out;
  }
  function channelCaption(c) {
    if (c.name === 'ct') return 'warped CT, ' + c.lo + ' to ' + c.hi + ' HU';
    if (c.name === 'displacement') return '|forward DVF|, 0 (dark) to ' + c.hi + ' mm (bright)';
    return 'Jacobian of the forward map, ' + c.lo + ' (blue, compressed) to ' + c.hi + ' (red, expanded), log scale';
  }
  function channelColor(c, b) {
    var f = b / 255;
    if (c.name === 'ct') return [b, b, b];
    if (c.name === 'displacement') {  // dark blue through teal to yellow
      return [Math.round(255 * Math.min(1, Math.max(0, 2 * f - 0.6))), Math.round(40 + 200 * f), Math.round(120 + 80 * Math.sin(Math.PI * f) - 100 * f)];
    }
    // Diverging about J = 1 (the byte 127.5 on the log scale): blue below, white at 1, red above.
    var d = (b - 127.5) / 127.5;
    return d < 0 ? [Math.round(255 * (1 + d)), Math.round(255 * (1 + d)), 255] : [255, Math.round(255 * (1 - d)), Math.round(255 * (1 - d))];
  }
  var LUNG_RGB = {};  // the lung colours as "r,g,b", for the self-test's count
  LUNG_COLORS.forEach(function (h) { LUNG_RGB[hexRgb(h).join(',')] = true; });
  function hexRgb(h) { return [parseInt(h.slice(1, 3), 16), parseInt(h.slice(3, 5), 16), parseInt(h.slice(5, 7), 16)]; }
  function nearestIndex(list, t) {
    var i = lowerIndex(list, t);
    return i + 1 < list.length && Math.abs(list[i + 1] - t) < Math.abs(list[i] - t) ? i + 1 : i;
  }
  // A point (LPS mm) on a plane's canvas, projected along the plane's normal: [column, row] with
  // pixel centres at +0.5 (row 0 the most superior).
  function planePixel(plane, x, y, z) {
    var o = plane.origin_mm, h = plane.pixel_mm;
    var across = plane.name === 'coronal' ? (x - o[0]) / h : (y - o[1]) / h;
    return [across + 0.5, plane.height - 1 - (z - o[2]) / h + 0.5];
  }
  // Each point's path over the run (a thin line) and, at the cursor's frame, its marker: a 3 x 3
  // square of its own colour (the self-test finds it by that colour).
  function drawTracks(s, frame) {
    var g = s.canvas.getContext('2d');
    g.globalAlpha = 0.6; g.lineWidth = 1;
    tracks.points.forEach(function (p, k) {  // every path first: no line over another point's marker
      g.strokeStyle = TRACK_COLORS[k % TRACK_COLORS.length];
      g.beginPath();
      for (var f = 0; f < tracks.times_s.length; ++f) {
        var q = planePixel(s.plane, p.x_mm[f], p.y_mm[f], p.z_mm[f]);
        if (f === 0) g.moveTo(q[0], q[1]); else g.lineTo(q[0], q[1]);
      }
      g.stroke();
    });
    g.globalAlpha = 1;
    tracks.points.forEach(function (p, k) {
      g.fillStyle = TRACK_COLORS[k % TRACK_COLORS.length];
      var m = planePixel(s.plane, p.x_mm[frame], p.y_mm[frame], p.z_mm[frame]);
      g.fillRect(Math.floor(m[0]) - 1, Math.floor(m[1]) - 1, 3, 3);
    });
  }
  function drawSlice(s, t) {
    var i = nearestIndex(s.plane.times_s, t);
    var frame = tracks ? nearestIndex(tracks.times_s, t) : -1;  // the points at the cursor's own frame
    if (i === s.shown && frame === s.frame) return;
    s.shown = i;
    s.frame = frame;
    var g = s.canvas.getContext('2d'), d = s.decoded[i];
    g.putImageData(d.image, 0, 0);
    if (s.reference >= 0) {  // dashed: the lungs' lowest point at end-expiration
      g.strokeStyle = '#ffffff'; g.lineWidth = 1; g.setLineDash([3, 3]);
      g.beginPath(); g.moveTo(0, s.reference + 1); g.lineTo(s.plane.width, s.reference + 1); g.stroke();
      g.setLineDash([]);
    }
    s.outlines.forEach(function (o, k) {  // the ITV's outline, then the structure's at the time shown over it
      g.fillStyle = ITV_COLORS[k % ITV_COLORS.length];
      o.itv.forEach(function (p) { g.fillRect(p % s.plane.width, Math.floor(p / s.plane.width), 1, 1); });
    });
    s.outlines.forEach(function (o, k) {
      g.fillStyle = STRUCTURE_COLORS[k % STRUCTURE_COLORS.length];
      o.masks[i].forEach(function (p) { g.fillRect(p % s.plane.width, Math.floor(p / s.plane.width), 1, 1); });
    });
    if (tracks) drawTracks(s, frame);
    s.channels.forEach(function (c) {
      var j = nearestIndex(s.plane.channel_times_s, t);
      if (j === c.shown) return;
      c.shown = j;
      c.canvas.getContext('2d').putImageData(c.images[j], 0, 0);
    });
    s.info.textContent = 't = ' + fmt(s.plane.times_s[i], 2) + ' s; dashed: the lowest lung at ' +
      fmt(s.reference_time, 2) + ' s; the lungs ' + fmt((d.lowest - s.reference) * s.plane.pixel_mm, 0) + ' mm lower';
  }

  function layoutPlots() { plots.forEach(function (p) { p.layout(); p.drawCursor(state.t); }); }
  listeners.push(function (t) { plots.forEach(function (p) { p.drawCursor(t); }); });

  // ---- controls ----
  var playButton = document.getElementById('play');
  var scrub = document.getElementById('scrub');
  var timeText = document.getElementById('time');
  scrub.max = String(duration);
  scrub.step = String(Math.min(frameStep, 0.01));
  function setPlaying(on) {
    state.playing = on;
    playButton.textContent = on ? 'Pause' : 'Play';
    lastTick = null;
  }
  playButton.addEventListener('click', function () { setPlaying(!state.playing); });
  scrub.addEventListener('input', function () { seek(parseFloat(scrub.value)); });
  document.getElementById('speed').addEventListener('change', function (e) { state.speed = parseFloat(e.target.value); });
  document.addEventListener('keydown', function (e) {
    var tag = e.target && e.target.tagName;
    if (tag === 'SELECT' || (tag === 'BUTTON' && e.key === ' ')) return;  // the button clicks itself
    if (tag === 'INPUT' && (e.target.type !== 'range' || e.key !== ' ')) return;  // the slider steps itself
    if (e.key === ' ') { setPlaying(!state.playing); e.preventDefault(); }
    else if (e.key === 'ArrowRight') { setPlaying(false); seek(state.t + frameStep); e.preventDefault(); }
    else if (e.key === 'ArrowLeft') { setPlaying(false); seek(state.t - frameStep); e.preventDefault(); }
  });
  listeners.push(function (t) {
    scrub.value = String(t);
    var b = binAt(t);
    timeText.textContent = 't = ' + t.toFixed(3) + ' s / ' + duration.toFixed(1) + ' s' +
      (b >= 0 ? ' \u00b7 bin ' + b + ' (' + fmt(bins.bins[b].percent, 0) + ' %)' : '');
  });

  // ---- the 3D view: the run's glb, its morph-weight animation driven by the shared clock ----
  var view = document.getElementById('view');
  var renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.gammaOutput = true;
  renderer.gammaFactor = 2.2;
  renderer.setClearColor(0xf4f5f7, 1);
  view.insertBefore(renderer.domElement, view.firstChild);
  var scene = new THREE.Scene();
  var camera = new THREE.PerspectiveCamera(35, 1, 0.001, 100);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x6d7380, 0.55));
  var key = new THREE.DirectionalLight(0xffffff, 0.75);
  key.position.set(0.6, 1.0, 1.2);
  scene.add(key);
  var rim = new THREE.DirectionalLight(0xffffff, 0.3);
  rim.position.set(-1.0, 0.2, -0.8);
  scene.add(rim);
  var controls = new THREE.OrbitControls(camera, renderer.domElement);
  controls.enableDamping = false;
  controls.enableKeys = false;  // the arrow keys step through time (below), not pan
  controls.addEventListener('change', function () { needsRender = true; });
  var mixer = null, action = null, lung = null, lungs = [], needsRender = true;

  function resize() {
    var w = Math.max(1, view.clientWidth), h = Math.max(1, view.clientHeight);
    renderer.setSize(w, h, false);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
    needsRender = true;
  }
  function render() {
    renderer.render(scene, camera);
    needsRender = false;
  }
  listeners.push(function (t) {
    if (action) {
      action.time = Math.min(t, action.getClip().duration);
      mixer.update(0);  // evaluates the clip at action.time (no time passes)
    }
    needsRender = true;
  });

  function regionColours(mesh, on) {
    var geometry = mesh.geometry, material = mesh.material;
    if (on && !geometry.attributes.color) {
      var labels = geometry.attributes._region, weights = geometry.attributes._region_weights;
      if (!labels) return;
      var names = (mesh.userData && mesh.userData.regionNames) || ['apex', 'costal', 'diaphragmatic', 'mediastinal'];
      var rgb = names.map(function (n) { return new THREE.Color(REGION_COLORS[n] || '#999999'); });
      var colors = new Float32Array(labels.count * 3);
      for (var i = 0; i < labels.count; ++i) {
        var c = new THREE.Color(0, 0, 0);
        if (weights) {
          for (var r = 0; r < 4 && r < rgb.length; ++r) {
            var w = weights.getComponent ? weights.getComponent(i, r) : weights.array[4 * i + r];
            c.r += w * rgb[r].r; c.g += w * rgb[r].g; c.b += w * rgb[r].b;
          }
        } else {
          c.copy(rgb[labels.getX(i)] || rgb[0]);
        }
        colors[3 * i] = c.r; colors[3 * i + 1] = c.g; colors[3 * i + 2] = c.b;
      }
      geometry.setAttribute('color', new THREE.BufferAttribute(colors, 3));
    }
    if (!mesh.userData.lungColor) mesh.userData.lungColor = material.color.clone();
    material.vertexColors = on ? THREE.VertexColors : THREE.NoColors;
    material.color.copy(on ? new THREE.Color(1, 1, 1) : mesh.userData.lungColor);
    material.needsUpdate = true;
    needsRender = true;
  }

  var loaded = new Promise(function (resolve, reject) {
    var bytes = base64ToBytes(document.getElementById('pneuma-glb').textContent);
    new THREE.GLTFLoader().parse(bytes.buffer, '', function (gltf) {
      scene.add(gltf.scene);
      gltf.scene.traverse(function (o) { if (o.isMesh) { if (!lung) lung = o; lungs.push(o); } });
      if (gltf.animations.length > 0) {
        mixer = new THREE.AnimationMixer(gltf.scene);
        action = mixer.clipAction(gltf.animations[0]);
        action.play();
      }
      // Frame the lung at rest: anterior-oblique view (glTF +z is the patient's anterior).
      var box = new THREE.Box3().setFromObject(gltf.scene);
      var centre = box.getCenter(new THREE.Vector3()), radius = box.getSize(new THREE.Vector3()).length() / 2;
      var distance = radius / Math.sin(THREE.Math.degToRad(camera.fov / 2)) * 0.8;
      camera.position.copy(centre).add(new THREE.Vector3(0.35, 0.12, 1).normalize().multiplyScalar(distance));
      camera.near = distance / 100; camera.far = distance * 10;
      camera.updateProjectionMatrix();
      controls.target.copy(centre);
      controls.update();
      document.getElementById('regions').addEventListener('change', function (e) {
        lungs.forEach(function (o) { regionColours(o, e.target.checked); });  // one mesh per lung
      });
      resolve();
    }, function (e) { reject(e); });
  });

  function tick(now) {
    if (state.playing) {
      if (lastTick !== null && duration > 0) {
        var t = state.t + (now - lastTick) / 1000 * state.speed;
        seek(t > duration ? t % duration : t);
      }
      lastTick = now;
    }
    if (needsRender) render();
    requestAnimationFrame(tick);
  }
  var lastTick = null;

  window.addEventListener('resize', function () { resize(); layoutPlots(); });

  // ---- self-test: render at the given times, read the canvas back, report as JSON ----
  function pixels() {
    var gl = renderer.getContext();
    var w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    var p = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, p);
    return { w: w, h: h, p: p };
  }
  function differs(a, i, b, j) {
    return Math.abs(a[i] - b[j]) + Math.abs(a[i + 1] - b[j + 1]) + Math.abs(a[i + 2] - b[j + 2]) > 24;
  }
  function selftest(at) {
    var result = { times_s: [], nonblank: [], weights: [], bins: [], slices: [], changed: 0, pixels: 0, samples: times.length,
                   rows: series.rows, stride: series.stride, glb_bytes: 0, errors: 0, messages: [] };
    var shots = at.map(function (t) {
      seek(t);
      render();
      var shot = pixels();
      var count = 0;
      for (var i = 0; i < shot.p.length; i += 4) if (differs(shot.p, i, shot.p, 0)) ++count;  // vs. the corner (background)
      result.times_s.push(state.t);
      result.nonblank.push(count);
      result.weights.push(lung && lung.morphTargetInfluences ? lung.morphTargetInfluences[0] : null);
      result.bins.push(binAt(state.t));
      result.slices.push(slicePlanes.map(function (s) {  // what the canvas shows, read back
        var p = s.canvas.getContext('2d').getImageData(0, 0, s.plane.width, s.plane.height).data, lungPixels = 0;
        for (var i = 0; i < p.length; i += 4) if (LUNG_RGB[p[i] + ',' + p[i + 1] + ',' + p[i + 2]]) ++lungPixels;
        var channelPixels = s.channels.map(function (c) {  // each channel canvas: pixels that are not background
          var q = c.canvas.getContext('2d').getImageData(0, 0, s.plane.width, s.plane.height).data, n = 0, sum = 0;
          for (var k = 0; k < q.length; k += 4) { sum += q[k] + q[k + 1] + q[k + 2]; if (q[k + 3] > 0) ++n; }
          return { name: c.channel.name, time_s: s.plane.channel_times_s[c.shown], drawn: n, mean_rgb: sum / (3 * Math.max(1, n)) };
        });
        // Each point's marker as drawn: the centre of the pixels of its colour (null when off the canvas).
        var markers = tracks ? tracks.points.map(function (pt, k) {
          var rgb = hexRgb(TRACK_COLORS[k % TRACK_COLORS.length]), n = 0, cx = 0, cy = 0;
          for (var i = 0; i < p.length; i += 4) {
            if (p[i] === rgb[0] && p[i + 1] === rgb[1] && p[i + 2] === rgb[2]) {
              var at = i / 4;
              ++n; cx += at % s.plane.width + 0.5; cy += Math.floor(at / s.plane.width) + 0.5;
            }
          }
          return { name: pt.name, frame: s.frame, time_s: tracks.times_s[s.frame], pixels: n,
                   column: n ? cx / n : null, row: n ? cy / n : null };
        }) : [];
        // Each structure's outline and its ITV's, counted by their colours as drawn.
        var outlines = s.outlines.map(function (o, k) {
          var a = hexRgb(STRUCTURE_COLORS[k % STRUCTURE_COLORS.length]), b = hexRgb(ITV_COLORS[k % ITV_COLORS.length]), n = 0, m = 0;
          for (var i = 0; i < p.length; i += 4) {
            if (p[i] === a[0] && p[i + 1] === a[1] && p[i + 2] === a[2]) ++n;
            if (p[i] === b[0] && p[i + 1] === b[1] && p[i + 2] === b[2]) ++m;
          }
          return { name: o.name, outline_pixels: n, itv_outline_pixels: m };
        });
        return { time_s: s.plane.times_s[s.shown], lung_pixels: lungPixels, channels: channelPixels, markers: markers,
                 structures: outlines };
      }));
      result.pixels = shot.w * shot.h;
      return shot;
    });
    for (var k = 1; k < shots.length; ++k) {
      for (var i = 0; i < shots[0].p.length; i += 4) if (differs(shots[0].p, i, shots[k].p, i)) ++result.changed;
    }
    result.glb_bytes = base64ToBytes(document.getElementById('pneuma-glb').textContent).length;
    result.ventilator = screen ? screen.shown : null;  // the screen at the last time
    result.ms = Math.round(performance.now());  // since navigation started: load, parse, both renders
    result.errors = errors.length;
    result.messages = errors.slice(0, 5);
    document.getElementById('selftest').textContent = JSON.stringify(result);
  }

  function start() {
    resize();
    layoutPlots();
    var hash = window.location.hash.replace(/^#/, '');
    var test = /(?:^|&)selftest=([0-9.,]+)/.exec(hash);
    var at = /(?:^|&)t=([0-9.]+)/.exec(hash);
    seek(at ? parseFloat(at[1]) : 0);
    if (/(?:^|&)regions(?:&|$)/.test(hash) && lung) {
      document.getElementById('regions').checked = true;
      regionColours(lung, true);
    }
    if (test) {
      selftest(test[1].split(',').map(parseFloat));
      return;
    }
    render();
    requestAnimationFrame(tick);
  }
  loaded.then(start, function (e) {
    errors.push('cannot read the embedded glb: ' + String(e && e.message || e));
    console.error('pneuma report: cannot read the embedded glb:', e);
    document.getElementById('selftest').textContent = JSON.stringify({ errors: errors.length, messages: errors });
  });
})();
