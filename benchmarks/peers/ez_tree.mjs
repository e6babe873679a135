// ez-tree (npm @dgreenheck/ez-tree, three.js) as a line server for benchmarks/bench_peers.py.
//
// Reads one command per line on stdin and answers one JSON line on stdout:
//   <preset name>   e.g. "Oak Large": generate that preset once ->
//                   {"preset": ..., "ms": <generate() wall time>, "triangles": <branches + leaves>,
//                    "branches": ..., "leaves": ...}
//   presets         -> {"presets": [...]}   (the preset names this ez-tree version knows)
//   quit            -> exits
// A bad command answers {"error": "..."} and the server keeps going. The Tree of each preset is
// created and its preset loaded once (the first time it is asked for); every later command only
// times tree.generate(). Warm-up runs are the caller's job.
//
// ez-tree loads its textures at import through three's TextureLoader, which needs a DOM; a tiny
// shim (set before the dynamic import) makes the image loads inert under node. Geometry is not
// affected: generate() builds the BufferGeometry of the branches and the leaves on the CPU.
import { performance } from 'node:perf_hooks';
import { createInterface } from 'node:readline';

globalThis.document = {
  createElementNS: () => ({ addEventListener() {}, removeEventListener() {}, set src(v) {}, style: {} }),
};
globalThis.self = globalThis;

const { Tree, TreePreset } = await import('@dgreenheck/ez-tree');

const trees = new Map();
const out = (obj) => process.stdout.write(JSON.stringify(obj) + '\n');

function run(preset) {
  if (!(preset in TreePreset)) return { error: `unknown preset: ${preset}` };
  let tree = trees.get(preset);
  if (!tree) {
    tree = new Tree();
    tree.loadPreset(preset); // (loadPreset also generates once)
    trees.set(preset, tree);
  }
  const t0 = performance.now();
  tree.generate();
  const ms = performance.now() - t0;
  const branches = tree.branchesMesh.geometry.index.count / 3;
  const leaves = tree.leavesMesh.geometry.index.count / 3;
  return { preset, ms, triangles: branches + leaves, branches, leaves };
}

const rl = createInterface({ input: process.stdin, terminal: false });
for await (const raw of rl) {
  const cmd = raw.trim();
  if (!cmd) continue;
  if (cmd === 'quit') break;
  if (cmd === 'presets') {
    out({ presets: Object.keys(TreePreset) });
    continue;
  }
  try {
    out(run(cmd));
  } catch (e) {
    out({ error: String(e && e.stack ? e.stack : e) });
  }
}
process.exit(0);
