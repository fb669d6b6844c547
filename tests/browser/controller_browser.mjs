// The controller process's page in headless Chromium (puppeteer-core): node controller_browser.mjs
// WEB_DIR CHROMIUM OUT_DIR URL. URL serves a running controller's page (rths controller --view,
// or test_view --serve-controller) while a host drives it. Checks, printing "ok ..." or
// "FAIL ..." lines and exiting 1 on any failure:
//  - the page loads and renders with no console error, page error or failed request;
//  - the oscilloscope trace grows without a reload: its latest controller time increases, and
//    it holds the loop's samples 1 ms apart (the page's data equals what the loop published);
//  - the lateness histogram counts the loop's samples;
//  - a screenshot (OUT_DIR/view_controller.png) is not blank: many distinct colours.
import path from "node:path";
import { createRequire } from "node:module";
import { fail, ok, openPage, runInBrowser, screenshot } from "./browser_common.mjs";

const [webDir, chromium, outDir, url] = process.argv.slice(2);
const puppeteer = createRequire(path.resolve(webDir, "package.json"))("puppeteer-core");

async function controllerPage(browser) {
  const problems = [];
  const page = await openPage(browser, url, "controller page", problems, 950);
  await page.waitForFunction(() => window.rthsView && window.rthsView.drawn.scope > 50, { timeout: 20000 });
  const seen = [];
  for (let i = 0; i < 8; i++) {
    seen.push(await page.evaluate(() => window.rthsView.drawn.scopeLastTime));
    await new Promise((r) => setTimeout(r, 500));
  }
  const grows = seen.every((t, i) => i === 0 || t >= seen[i - 1]) && seen[seen.length - 1] > seen[0];
  if (grows) ok(`scope trace grows without a reload: latest controller time ${seen.map((t) => t.toFixed(3)).join(" ")} s`);
  else fail(`scope trace did not grow: ${seen.join(" ")}`);
  const spacing = await page.evaluate(() => {
    const t = window.rthsView.state.process.scope.time_s;
    let worst = 0;
    for (let i = 1; i < t.length; i++) worst = Math.max(worst, Math.abs(t[i] - t[i - 1] - 1e-3));
    return { n: t.length, worst };
  });
  // %.9g times: 1e-6 s resolution below 1000 s of controller time
  if (spacing.n > 50 && spacing.worst < 2e-6) ok(`scope holds ${spacing.n} loop samples 1 ms apart (worst deviation ${spacing.worst.toExponential(1)} s)`);
  else fail(`scope spacing: ${JSON.stringify(spacing)}`);
  const moving = await page.evaluate(() => {
    const x = window.rthsView.state.process.scope.x_phys_m.filter((v) => v != null);
    return Math.max(...x) - Math.min(...x);
  });
  if (moving > 1e-7) ok(`the physical interface moves: ${(moving * 1e6).toFixed(2)} µm peak to peak in the window`);
  else fail(`the physical interface does not move (${moving} m): is the host driving it?`);
  const counted = await page.evaluate(() => window.rthsView.drawn.lateness.reduce((a, b) => a + b, 0));
  const samples = await page.evaluate(() => window.rthsView.state.process.state.samples);
  if (counted > 0 && counted <= samples + 1) ok(`lateness histogram counts ${counted} wake-ups (${samples} samples)`);
  else fail(`lateness histogram: ${counted} counted, ${samples} samples`);
  const file = path.join(outDir, "view_controller.png");
  await screenshot(page, file);
  await page.close();
  return problems;
}

await runInBrowser(puppeteer, chromium, outDir, "controller page", [controllerPage]);
