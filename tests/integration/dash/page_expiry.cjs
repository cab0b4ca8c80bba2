// tests/integration/dash/page_expiry.cjs (ctest torque_dash_page_expiry): the dashboard page's script
// (tools/dash/www/dash.js) in node with a stub DOM: engines the server expires ({"expired":[ids]}, tools/dash/
// hub.cpp) leave the page's engine list, its state and the selection; a later sample of the same id brings it
// back. Usage: node page_expiry.cjs <dash.js>
'use strict';
const fs = require('fs');
const vm = require('vm');
// Any DOM object or Chart: a callable proxy whose every property is another one (charts, tables, badges).
const any = () => new Proxy(function () {}, {get: (t, k) => (k === Symbol.toPrimitive ? () => '' : any()),
                                              set: () => true, apply: () => any(), construct: () => any()});
const select = {value: '', children: [], addEventListener() {},
                appendChild(o) { o.remove = () => { this.children = this.children.filter(c => c !== o); };
                                 this.children.push(o); },
                get options() { return this.children; }};
let socket = null;
const ctx = {
  console, setTimeout: () => 0, Map, Set, Number, Object, Math, JSON, Array, String,
  location: {host: '127.0.0.1:1'},
  document: {getElementById: id => (id === 'engine' ? select : any()), querySelector: () => any(),
             createElement: () => ({value: '', textContent: ''})},
  Chart: function () { return any(); },
  WebSocket: function () { socket = this; },
};
ctx.window = ctx;
vm.createContext(ctx);
vm.runInContext(fs.readFileSync(process.argv[2], 'utf8'), ctx);
const send = m => socket.onmessage({data: JSON.stringify(m)});
const engine = () => ({torque: [[1.0, 1, 0, 1, 1000, 10, 20, 10, 0, 0]], incycle: [], unplaced: 0});
const ids = () => select.options.map(o => Number(o.value)).join(',');
let failed = 0;
const check = (ok, what) => { console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}`); failed += ok ? 0 : 1; };
send({engines: {7: engine(), 100: engine(), 101: engine()}});
check(ids() === '7,100,101' && ctx.dashState.selected === 7, `three engines listed (${ids()}), 7 selected`);
send({engines: {}, expired: [7, 100]});
check(ids() === '101' && !ctx.dashState.engines.has(7) && !ctx.dashState.engines.has(100),
      `expired 7 and 100 leave the list and the state (${ids()})`);
check(ctx.dashState.selected === 101, `the selection moves to the engine left (${ctx.dashState.selected})`);
send({engines: {}, expired: [101]});
check(ids() === '' && ctx.dashState.selected === null, 'the last engine expired: empty list, nothing selected');
send({engines: {7: engine()}});
check(ids() === '7' && ctx.dashState.selected === 7, 'engine 7 speaks again: listed and selected');
process.exit(failed ? 1 : 0);
