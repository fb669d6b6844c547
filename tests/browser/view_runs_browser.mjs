// Finished runs of other shapes in headless Chromium: node view_runs_browser.mjs WEB_DIR CHROMIUM
// OUT_DIR NAME URL RUN_DIR [NAME URL RUN_DIR]... For each: the page renders with no console
// error, draws frf.csv's points number for number for every interface DoF (dof<d>_amplitude_m),
// draws exactly the points frf.csv labels unstable as open markers, and a screenshot
// OUT_DIR/view_NAME.png is not blank. Prints "ok ..."/"FAIL ..." lines, exits 1 on a failure.
import path from "node:path";
import { createRequire } from "node:module";
import { drawsCsv, openPage, runInBrowser, screenshot } from "./browser_common.mjs";

const [webDir, chromium, outDir, ...runs] = process.argv.slice(2);
// puppeteer-core is web/'s devDependency (web/package-lock.json), installed by `make deps`
const puppeteer = createRequire(path.resolve(webDir, "package.json"))("puppeteer-core");

function pageTest(name, url, dir) {
  return async (browser) => {
    const problems = [];
    const page = await openPage(browser, url, name, problems);
    await page.waitForFunction(() => window.rthsView && window.rthsView.renders > 0 && window.rthsView.drawn.frf.length > 0, { timeout: 15000 });
    await new Promise((r) => setTimeout(r, 800)); // the event stream's first change, then idle
    await drawsCsv(page, path.join(dir, "frf.csv"));
    await screenshot(page, path.join(outDir, `view_${name}.png`));
    await page.close();
    return problems;
  };
}

const tests = [];
for (let i = 0; i + 2 < runs.length; i += 3) tests.push(pageTest(runs[i], runs[i + 1], runs[i + 2]));
await runInBrowser(puppeteer, chromium, outDir, "other runs' pages", tests);
