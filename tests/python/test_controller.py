"""rths.controller and rths.controller_latency (the C API's rths_api_controller_start / _stop /
_latency, `rths controller` for a program): a controller served in this process on 127.0.0.1 with
a free port answers a hybrid test as the in-process virtual rig does, and is stopped whatever the
test's outcome (its port refuses connections afterwards). Run by tests/cli/python.sh."""
import os
import socket
import unittest
import urllib.request

import numpy as np

import rths

SRC = os.environ["RTHS_SOURCE_DIR"]
SEED_CFG = os.path.join(SRC, "examples", "four_storey.yaml")


def refused(port):
    """True when nothing listens on 127.0.0.1:port any more."""
    with socket.socket() as s:
        try:
            s.connect(("127.0.0.1", port))
        except ConnectionRefusedError:
            return True
    return False


class Controller(unittest.TestCase):
    def test_a_test_against_the_served_controller_matches_the_virtual_rig(self):
        cfg = rths.Config.load(SEED_CFG)
        with rths.controller(cfg, view="127.0.0.1:0") as ctl:
            self.assertRegex(ctl.rig, r"^tcp://127\.0\.0\.1:\d+$")
            self.assertGreater(ctl.port, 0)
            with urllib.request.urlopen(ctl.view_url, timeout=10) as page:
                self.assertEqual(page.status, 200)
            remote = rths.simulate(cfg, 13.4, 10, target=[1e-4, 0], rig=ctl.rig)
        port = ctl.port
        virtual = rths.simulate(cfg, 13.4, 10, target=[1e-4, 0], seed=3)
        # The controller process runs the same step and simulated plant as the virtual rig, one
        # sample at a time on its own clock (lateness moves when a sample runs, not what it
        # computes): the last periods' coefficients agree to the sensors' noise, which moves them
        # by about 0.02 % between seeds (1 % leaves a margin of 50).
        for name in ("phys_a1_m", "phys_b1_m"):
            r, v = remote.coefficients[name][-3:], virtual.coefficients[name][-3:]
            np.testing.assert_allclose(r, v, rtol=1e-2, err_msg=name)
        self.assertTrue(np.all(remote.coefficients["period"] == np.arange(1, 11)))
        # stopped by the with-block: the statistics are kept, the port is closed
        self.assertGreater(ctl.stats["samples"], 0)
        self.assertEqual(ctl.stats["fault"], 0)
        self.assertTrue(refused(port))
        self.assertIs(ctl.stop(), ctl.stats)  # a second stop changes nothing

    def test_stopped_whatever_the_outcome(self):
        cfg = rths.Config.load(SEED_CFG)
        port = None
        with self.assertRaises(ZeroDivisionError):
            with rths.controller(cfg) as ctl:
                port = ctl.port
                1 / 0
        self.assertTrue(refused(port))

    def test_bad_input_is_refused_before_anything_runs(self):
        cfg = rths.Config.load(SEED_CFG)
        with self.assertRaises(rths.InputError) as e:
            rths.controller(cfg, listen="localhost")
        self.assertEqual(str(e.exception),
                         "listen 'localhost': expected ADDR:PORT (port 0..65535)")
        with self.assertRaises(rths.InputError) as e:
            rths.controller(cfg.with_set({"server.watchdog_s": -1}))
        self.assertIn("server.watchdog_s", str(e.exception))
        with self.assertRaises(rths.InputError):
            rths.controller(cfg, site=0)  # sites count from 1

    def test_latency_test_counts_its_samples(self):
        # the paced loop alone: seconds x controller.sample_rate_hz samples, exactly
        lat = rths.controller_latency(0.2)
        self.assertEqual(lat.summary["samples"], 2000)
        self.assertEqual(lat.summary["sample_rate_hz"], 10000)
        self.assertTrue(lat.text.startswith("samples 2000 at 10000 Hz: wake-up lateness p50 "))
        lat = rths.controller_latency(0.1, rths.Config.load(
            SEED_CFG, set={"controller.sample_rate_hz": 5000}))
        self.assertEqual(lat.summary["samples"], 500)
        self.assertLessEqual(lat.summary["lateness_p50_s"], lat.summary["worst_lateness_s"])
        with self.assertRaises(rths.InputError):
            rths.controller_latency(0)


if __name__ == "__main__":
    unittest.main()
