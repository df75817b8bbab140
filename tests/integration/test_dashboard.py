"""The dashboard in a real browser (docs/architecture.md, "The browser view"): softshockd with
--http-listen, Debian's headless Chromium driven by chromium-driver and python3-selenium
(scripts/install-deps). It signs in with the token, watches the jobs table while a job waits
behind a running one and then finishes (its row's state changes from QUEUED to SUCCEEDED without
a reload), filters and sorts the table, and opens the job page, whose Ā(t) polyline must have one
vertex per sample GetTimeSeries returns, whose rim-mode heat map has GetModes' cells and whose
field slider walks the result's frames. A wrong token is refused at the sign-in form.

SOFTSHOCK_DASHBOARD_SCREENSHOTS=DIR saves the pages as PNG files there (docs/img/ holds the
ones the docs show)."""

import os
import time
import unittest

from selenium import webdriver
from selenium.common.exceptions import StaleElementReferenceException, WebDriverException
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select

from softshock_harness import DaemonTestCase, long_spec, small_spec, state_name

TOKEN = "dashboard-token-0123456789abcdef012345678"
CHROMIUM = os.environ.get("SOFTSHOCK_CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("SOFTSHOCK_CHROMEDRIVER", "/usr/bin/chromedriver")


def browser() -> webdriver.Chrome:
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1360,1000", "--no-first-run", "--disable-extensions",
                "--disable-background-networking", "--disable-component-update"):
        options.add_argument(arg)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


class DashboardTest(DaemonTestCase):
    start_daemon = False
    workers = 1  # the second job waits for the first: a state change to watch

    def setUp(self):
        super().setUp()
        token_file = self.write_json(TOKEN + "\n", "token")
        port_file = os.path.join(self.tmp, "http.port")
        self.daemon.extra_args += ["--token-file", token_file, "--http-listen", "127.0.0.1:0",
                                   "--http-port-file", port_file]
        self.start(health_token=TOKEN)
        with open(port_file, encoding="utf-8") as f:
            self.url = f"http://127.0.0.1:{int(f.read().strip().rsplit(':', 1)[-1])}/"
        self.driver = browser()
        self.addCleanup(self.driver.quit)
        self.driver.set_page_load_timeout(30)
        self.shots = os.environ.get("SOFTSHOCK_DASHBOARD_SCREENSHOTS", "")

    # -- helpers -------------------------------------------------------------------------------
    def js(self, script, *args):
        return self.driver.execute_script(script, *args)

    def until(self, predicate, timeout=60.0, what="condition"):
        deadline = time.monotonic() + timeout
        while True:
            try:
                value = predicate()
            except (StaleElementReferenceException, WebDriverException):
                value = None  # the page re-rendered under us: ask again
            if value:
                return value
            if time.monotonic() > deadline:
                logs = ""
                try:
                    logs = "\n".join(str(e) for e in self.driver.get_log("browser"))
                except WebDriverException:
                    pass
                self.fail(f"timed out after {timeout} s waiting for {what}\nbrowser log:\n{logs}")
            time.sleep(0.1)

    def sign_in(self, token=TOKEN):
        self.driver.get(self.url)
        box = self.until(lambda: self.driver.find_element(By.ID, "token").is_displayed() and
                         self.driver.find_element(By.ID, "token"), what="the sign-in form")
        box.send_keys(token)
        self.driver.find_element(By.ID, "sign-in").click()

    def row_states(self):
        """{job id: state} of the jobs table's rows, in the table's order."""
        return self.js("""return [...document.querySelectorAll('#jobs-table tbody tr')]
                          .map(tr => [tr.dataset.jobId, tr.dataset.state]);""")

    def screenshot(self, name):
        if self.shots:
            os.makedirs(self.shots, exist_ok=True)
            self.driver.save_screenshot(os.path.join(self.shots, name))

    # -- tests ---------------------------------------------------------------------------------
    def test_a_wrong_token_is_refused_at_sign_in(self):
        self.sign_in("not-the-token-0123456789abcdef01234567")
        error = self.until(lambda: self.driver.find_element(By.ID, "login-error").text,
                           what="the sign-in error")
        self.assertIn("refused", error)
        self.assertEqual(self.driver.find_element(By.ID, "who").text, "")
        self.assertEqual(self.js("return document.querySelectorAll('#jobs-table').length"), 0)

    def test_jobs_table_and_job_page(self):
        self.sign_in()
        self.until(lambda: "default" in self.driver.find_element(By.ID, "who").text,
                   what="the caller in the header")
        self.until(lambda: self.driver.find_element(By.ID, "jobs-count").text.startswith("0 job"),
                   what="the empty table")

        # A long job takes the one worker; a small one waits behind it. 2 us: the default 600 ns
        # ran in 1.4 s on a fast machine, under two of the page's 1 s polls.
        c = self.client(token=TOKEN)
        first = c.submit(long_spec(end_time=2e-6), labels={"study": "long"})
        small = c.submit(small_spec(elements=400, end_time=4e-8), labels={"study": "small"})
        seen = []  # the small job's states as its row showed them, in order
        fractions = set()  # the running job's progress as its row's bar showed it

        def small_done():
            states = dict(self.row_states())
            s = states.get(small.id)
            if s and (not seen or seen[-1] != s):
                seen.append(s)
            if states.get(first.id) == "RUNNING":
                fractions.add(float(self.js(
                    "return document.querySelector('#jobs-table tr[data-job-id=\"' + "
                    "arguments[0] + '\"] .bar').dataset.fraction", first.id)))
            if states.get(first.id) == "RUNNING" and not self.shots_taken:
                self.shots_taken = True
                self.screenshot("dashboard_jobs_running.png")
            return s == "SUCCEEDED" and states.get(first.id) == "SUCCEEDED"

        self.shots_taken = False
        self.until(small_done, timeout=180, what="both jobs SUCCEEDED in the table")
        self.assertEqual(seen[0], "QUEUED", seen)
        self.assertEqual(seen[-1], "SUCCEEDED", seen)
        # Live progress: the bar moved while the page was open, without a reload.
        moving = sorted(f for f in fractions if 0 < f < 1)
        self.assertGreaterEqual(len(moving), 2, fractions)
        self.assertEqual(state_name(c.get(small.id)), "SUCCEEDED")
        rows = self.row_states()
        self.assertEqual(len(rows), 2)
        self.assertEqual(rows[0][0], small.id, "newest first")
        progress = self.js("""return document.querySelector(
            '#jobs-table tr[data-job-id="' + arguments[0] + '"] .bar').dataset.fraction""",
                           small.id)
        self.assertEqual(float(progress), 1.0)

        # Filters: a label on the server, a parameter condition in the page.
        self.driver.find_element(By.ID, "filter-label").send_keys("study=small")
        self.driver.find_element(By.ID, "filter-apply").click()
        self.until(lambda: [r[0] for r in self.row_states()] == [small.id], what="label filter")
        self.driver.find_element(By.ID, "filter-label").clear()
        self.driver.find_element(By.ID, "filter-param").send_keys("geometry.target_elements>1000")
        self.driver.find_element(By.ID, "filter-apply").click()
        self.until(lambda: [r[0] for r in self.row_states()] == [first.id], what="param filter")
        self.driver.find_element(By.ID, "filter-param").clear()
        Select(self.driver.find_element(By.ID, "filter-state")).select_by_value("RUNNING")
        self.driver.find_element(By.ID, "filter-apply").click()
        self.until(lambda: self.row_states() == [], what="no RUNNING job")
        Select(self.driver.find_element(By.ID, "filter-state")).select_by_value("")
        self.driver.find_element(By.ID, "filter-apply").click()
        self.until(lambda: len(self.row_states()) == 2, what="both rows again")
        # Sorting by elements, ascending: the small job first; again: descending.
        header = self.driver.find_element(By.CSS_SELECTOR, '#jobs-table th[data-key="elements"]')
        header.click()
        self.until(lambda: [r[0] for r in self.row_states()] == [small.id, first.id],
                   what="ascending sort")
        self.driver.find_element(By.CSS_SELECTOR, '#jobs-table th[data-key="elements"]').click()
        self.until(lambda: [r[0] for r in self.row_states()] == [first.id, small.id],
                   what="descending sort")
        self.screenshot("dashboard_jobs.png")

        # The job page: Ā(t) drawn from GetTimeSeries' samples, the modes map, the field.
        self.driver.find_element(By.LINK_TEXT, small.id).click()
        self.until(lambda: self.driver.find_element(By.ID, "job-state").get_attribute(
            "data-state") == "SUCCEEDED", what="the job page's state")
        abar = self.until(lambda: self.driver.find_elements(
            By.CSS_SELECTOR, '#abar-plot polyline.series[data-series="Ā"]'), what="the Ā plot")
        series = c.series(small.id, ["abar"])
        finite = [v for v in series["abar"] if v == v]
        self.assertGreater(len(finite), 10)
        self.assertEqual(int(abar[0].get_attribute("data-points")), len(finite))
        self.assertEqual(len(abar[0].get_attribute("points").split()), len(finite))
        times, modes, amplitude = c.modes(small.id)
        cells = self.until(lambda: self.driver.find_element(By.ID, "modes-map").get_attribute(
            "data-cells"), what="the modes map")
        self.assertEqual(self.driver.find_element(By.ID, "modes-map").get_attribute("data-rows"),
                         str(len(modes)))
        self.assertEqual(self.driver.find_element(By.ID, "modes-map").get_attribute("data-cols"),
                         str(len(times)))
        self.assertGreater(int(cells), 0)
        summary_steps = self.driver.find_element(
            By.CSS_SELECTOR, '#job-summary tr[data-figure="steps"] td:nth-child(2)').text
        self.assertEqual(float(summary_steps), float(c.summary(small.id)["steps"]))
        # Figures under the names they have with units (a renamed figure shows "—").
        for figure in ("end_time_s", "wall_time_s", "energy_injected_J_per_m", "grind_ns"):
            shown = self.driver.find_element(
                By.CSS_SELECTOR, f'#job-summary tr[data-figure="{figure}"] td:nth-child(2)').text
            self.assertNotEqual(shown, "\u2014", figure)
        shown_end = self.driver.find_element(
            By.CSS_SELECTOR, '#job-summary tr[data-figure="end_time_s"] td:nth-child(2)').text
        self.assertAlmostEqual(float(shown_end), c.summary(small.id)["end_time_s"],
                               delta=5e-3 * c.summary(small.id)["end_time_s"])
        # The field: the last frame first, then the slider back to frame 0.
        caption = self.until(lambda: self.driver.find_element(By.ID, "field-caption").text
                             .startswith("frame") and
                             self.driver.find_element(By.ID, "field-caption").text,
                             what="the field picture")
        slider = self.driver.find_element(By.ID, "frame-slider")
        frames = int(slider.get_attribute("max")) + 1
        self.assertGreaterEqual(frames, 5)  # 40 ns every 5 ns: 9 frames
        self.assertIn(f"frame {frames} of {frames}", caption)
        self.assertEqual(self.driver.find_element(By.ID, "field-canvas").get_attribute(
            "data-frame"), str(frames - 1))
        self.js("""const s = document.getElementById('frame-slider'); s.value = 0;
                   s.dispatchEvent(new Event('input'));""")
        self.until(lambda: self.driver.find_element(By.ID, "field-canvas").get_attribute(
            "data-frame") == "0", what="frame 0 after moving the slider")
        self.assertIn(f"frame 1 of {frames}",
                      self.driver.find_element(By.ID, "field-caption").text)
        self.js("document.getElementById('frame-slider').value = arguments[0];"
                "document.getElementById('frame-slider').dispatchEvent(new Event('input'));",
                frames // 2)
        self.until(lambda: self.driver.find_element(By.ID, "field-canvas").get_attribute(
            "data-frame") == str(frames // 2), what="the middle frame")
        self.js("document.getElementById('job-summary').scrollIntoView()")
        self.screenshot("dashboard_job.png")
        self.js("document.getElementById('abar-box').scrollIntoView()")
        self.screenshot("dashboard_job_plots.png")
        self.js("document.getElementById('field-canvas').scrollIntoView(false)")
        self.screenshot("dashboard_job_field.png")
        # No script error; the one failed request is the first look for a caller, before
        # the sign-in, which the daemon answers 401.
        logs = [e for e in self.driver.get_log("browser") if e.get("level") == "SEVERE" and
                not ("/api/caller" in e["message"] and "401" in e["message"])]
        self.assertEqual(logs, [], "the browser logged errors")

    def test_grid_and_compare_pages(self):
        c = self.client(token=TOKEN)
        grid = c.submit_grid(small_spec(elements=300, end_time=2e-8),
                             [{"name": "pbar", "values": [0.5, 1.0]},
                              {"name": "tbar_pulse", "values": [0.06, 0.12, 0.18]}], wait=True)
        self.assertEqual(state_name(grid), "SUCCEEDED")
        reduction = c.grid_reduction(grid.id, "max_abar")
        self.sign_in()
        self.until(lambda: "default" in self.driver.find_element(By.ID, "who").text,
                   what="the caller in the header")

        # The grids list links to the grid; its map has one cell per point, coloured by value.
        self.driver.find_element(By.CSS_SELECTOR, '[data-nav="grids"]').click()
        self.until(lambda: self.driver.find_elements(By.LINK_TEXT, grid.id),
                   what="the grid in the list")[0].click()
        self.until(lambda: self.driver.find_element(By.ID, "grid-state").get_attribute(
            "data-state") == "SUCCEEDED", what="the grid's state")
        # The quantities are the daemon's grid figures (api/figures), damage ones included.
        self.until(lambda: self.driver.find_elements(
            By.CSS_SELECTOR, '#grid-quantity option[value="damage_onset_s"]'),
            what="the quantities from api/figures")
        Select(self.driver.find_element(By.ID, "grid-quantity")).select_by_value("max_abar")
        cells = self.until(lambda: self.driver.find_elements(
            By.CSS_SELECTOR, "#grid-map rect.cell"), what="the grid map")
        self.assertEqual(len(cells), 6)
        shown = {e.get_attribute("data-job-id"): float(e.get_attribute("data-value"))
                 for e in cells}
        expected = dict(zip(reduction.job_ids.ravel(), [float(v) for v in reduction.values.ravel()]))
        self.assertEqual(set(shown), set(expected))
        for job, value in expected.items():
            self.assertAlmostEqual(shown[job], value, delta=1e-9 + 1e-6 * abs(value), msg=job)
        self.screenshot("dashboard_grid.png")

        # A cell leads to its job; two points compared: the differing spec field and Ā(t) each.
        lo, hi = sorted(expected, key=expected.get)[0], sorted(expected, key=expected.get)[-1]
        self.js("document.querySelector('#grid-map rect.cell[data-job-id=\"' + arguments[0] +"
                " '\"]').dispatchEvent(new MouseEvent('click', {bubbles: true}))", lo)
        self.until(lambda: self.driver.current_url.endswith("#/jobs/" + lo), what="the job page")
        self.until(lambda: self.driver.find_element(By.ID, "job-state").get_attribute(
            "data-state") == "SUCCEEDED", what="the point's job page")
        self.driver.get(self.url + f"#/compare/{lo},{hi}")
        self.until(lambda: "default" in self.driver.find_element(By.ID, "who").text,
                   what="signed in again from the tab's session")
        lines = self.until(lambda: self.driver.find_elements(
            By.CSS_SELECTOR, "#compare-plot polyline.series"), what="the compare plot")
        self.assertEqual(sorted(e.get_attribute("data-series") for e in lines), sorted([lo, hi]))
        for e in lines:
            self.assertGreater(int(e.get_attribute("data-points")), 10)
        paths = [e.get_attribute("data-path") for e in self.driver.find_elements(
            By.CSS_SELECTOR, "#compare-spec tr[data-path]")]
        self.assertTrue(paths, "no differing spec field shown")
        self.assertTrue(all(p.startswith("load.") for p in paths), paths)
        self.driver.set_window_size(1360, 1400)
        self.js("document.getElementById('compare-summary').scrollIntoView()")
        self.screenshot("dashboard_compare.png")


if __name__ == "__main__":
    unittest.main()
