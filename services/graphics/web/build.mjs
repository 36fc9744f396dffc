// Build the live view into ../static/: bundle src/app.js with three.js (from node_modules, installed from the
// npm registry by `npm ci`) into one minified app.js, and copy the HTML and CSS. No CDN at run time.
import { build } from "esbuild";
import { createHash } from "node:crypto";
import { copyFileSync, mkdirSync, readFileSync, writeFileSync } from "node:fs";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

const here = dirname(fileURLToPath(import.meta.url));
const out = join(here, "..", "static");
mkdirSync(out, { recursive: true });
const threeVersion = JSON.parse(readFileSync(join(here, "node_modules", "three", "package.json"), "utf8")).version;
await build({
  entryPoints: [join(here, "src", "app.js")],
  bundle: true,
  minify: true,
  format: "iife",
  target: ["es2020"],
  legalComments: "eof",
  outfile: join(out, "app.js"),
  banner: { js: `/* Batteur live view; bundles three.js ${threeVersion} (MIT) from the npm registry */` },
  logLevel: "warning",
});
copyFileSync(join(here, "src", "index.html"), join(out, "index.html"));
copyFileSync(join(here, "src", "style.css"), join(out, "style.css"));
// what the bundle was built from, so a test can tell a stale bundle
const sources = Object.fromEntries(["app.js", "index.html", "style.css"].map((name) =>
  [name, createHash("sha256").update(readFileSync(join(here, "src", name))).digest("hex")]));
writeFileSync(join(out, "BUILD.json"), JSON.stringify({ three: threeVersion, sources }, null, 2) + "\n");
console.log(`built ${out} (three.js ${threeVersion})`);
