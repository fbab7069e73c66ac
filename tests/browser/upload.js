// Uploads a mesh through the start page's form in headless Chromium
// (puppeteer-core driving the system chromium), follows the page to the job
// page, records the progress bar until the job is final, waits for the
// previews, takes a full-page screenshot, and prints one JSON line:
// {url, id, progress_seen, states_seen, final_state, images, downloads}.
// With TOKEN, the start page is expected to ask for it (the server needs
// one): it is typed into the token box before the upload.
// Usage: node upload.js CHROMIUM BASE_URL MESH_FILE STAGES SCREENSHOT.png [TOKEN]
'use strict';

const puppeteer = require('puppeteer-core');

const TIMEOUT_MS = 120000;

function sleep(ms) { return new Promise((r) => setTimeout(r, ms)); }

/** Reads the job page's progress, final state and previews. */
function pageState() {
  const bar = document.getElementById('progress');
  return {
    progress: bar ? Number(bar.dataset.progress) : null,
    state: (document.getElementById('state') || {}).textContent || null,
    final: document.body.dataset.final || null,
    images: [...document.querySelectorAll('img[data-artifact]')].map((img) => ({
      name: img.dataset.artifact,
      blob: img.src.startsWith('blob:'),
      width: Number(img.dataset.naturalWidth || 0),
      failed: img.dataset.failed === 'true',
    })),
    downloads: [...document.querySelectorAll('a.download')].map((a) => ({
      name: a.textContent, href: a.getAttribute('href'), bytes: Number(a.dataset.bytes),
    })),
  };
}

async function main() {
  const [chromium, base, file, stages, screenshot, token] = process.argv.slice(2);
  const browser = await puppeteer.launch({
    executablePath: chromium,
    headless: true,
    args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage'],
  });
  try {
    const page = await browser.newPage();
    await page.setViewport({ width: 1280, height: 1000 });
    const consoleErrors = [];
    page.on('console', (m) => { if (m.type() === 'error') consoleErrors.push(m.text()); });
    page.on('pageerror', (e) => consoleErrors.push(String(e)));
    await page.goto(base + '/', { waitUntil: 'domcontentloaded' });
    if (token) {
      await page.waitForSelector('#auth:not([hidden]) #auth-token');
      await page.type('#auth-token', token);
      await Promise.all([page.waitForNavigation(), page.click('#auth-form button')]);
      consoleErrors.length = 0; // the 401 that asked for the token is expected
    }
    await page.waitForSelector('#upload #file');
    await (await page.$('#file')).uploadFile(file);
    for (const s of stages.split(',').filter(Boolean)) await page.click(`input[name=stage][value="${s}"]`);
    await Promise.all([page.waitForNavigation({ timeout: TIMEOUT_MS }), page.click('#submit')]);
    const url = page.url();
    const progressSeen = [];
    const statesSeen = [];
    const start = Date.now();
    let st;
    for (;;) {
      st = await page.evaluate(pageState);
      if (st.progress !== null && progressSeen[progressSeen.length - 1] !== st.progress) progressSeen.push(st.progress);
      if (st.state && statesSeen[statesSeen.length - 1] !== st.state) statesSeen.push(st.state);
      if (st.final) break;
      if (Date.now() - start > TIMEOUT_MS) throw new Error('the job page never reached a final state');
      await sleep(100);
    }
    // Previews settle: every image loaded or failed.
    while (st.images.some((i) => !i.width && !i.failed) && Date.now() - start < TIMEOUT_MS) {
      await sleep(100);
      st = await page.evaluate(pageState);
    }
    await page.screenshot({ path: screenshot, fullPage: true });
    const id = new URL(url).pathname.split('/').pop();
    console.log(JSON.stringify({
      url, id, progress_seen: progressSeen, states_seen: statesSeen, final_state: st.final,
      images: st.images, downloads: st.downloads, console_errors: consoleErrors,
    }));
  } finally {
    await browser.close();
  }
}

main().catch((e) => {
  console.error(`upload.js: ${e && e.stack ? e.stack : e}`);
  process.exit(1);
});
