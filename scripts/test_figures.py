"""Tests of scripts/figures: markers, formats, extraction, the drift check and the docs check.

    python3 scripts/test_figures.py
"""

import importlib.machinery
import importlib.util
import os
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
loader = importlib.machinery.SourceFileLoader("figures", os.path.join(HERE, "figures"))
spec = importlib.util.spec_from_loader("figures", loader)
figures = importlib.util.module_from_spec(spec)
loader.exec_module(figures)

FOOTPRINT = """\
| measure | value | target |
| --- | --- | --- |
| instructions: Cmaes<18, 12>, ask + tell (one evaluation) | median 7304, mean 38063, min 6922, max 473715 (n = 400) |  |
| size_of Adapter with Cmaes<18, 12> | 4768 B | ≤ 3 KB (adapter with its optimizer) |

Instruction counts: exact
"""

RESULTS = {
    "producers": {
        "fw": {"command": "bash scripts/footprint", "speed": "fast", "log": "fw.log"},
        "hop": {"command": "cargo run --example hop", "speed": "slow", "log": "hop.log"},
    },
    "figures": {
        "mean": {
            "producer": "fw",
            "value": "38063",
            "pattern": r"^\| instructions: Cmaes<18, 12>, ask \+ tell \(one evaluation\) \| median \d+, mean (\d+)",
        },
        "size": {"producer": "fw", "value": "4768", "pattern": r"^\| size_of Adapter with Cmaes<18, 12> \| (\d+) B"},
        "runs": {"producer": "hop", "value": "2", "pattern": r"^run \d+: ([\d.]+) cm", "reduce": "count_le:1.5",
                 "measured": {"commit": "0123456789ab", "date": "2026-01-01"}},
    },
}


class Formats(unittest.TestCase):
    def test_formats(self):
        self.assertEqual(figures.fmt("38446", "c"), "38,446")
        self.assertEqual(figures.fmt("1.0845e3", "c0"), "1,085")  # half up, not half to even
        self.assertEqual(figures.fmt("15280", "kf1"), "15.3")
        self.assertEqual(figures.fmt("1703160", "Mf2"), "1.70")
        self.assertEqual(figures.fmt("-3.2827", "f2u"), "−3.28")
        self.assertEqual(figures.fmt("12000", "s"), "12 000")
        self.assertEqual(figures.fmt("-3.2827", "f2a"), "3.28")
        self.assertEqual(figures.fmt("text | kept", "block"), "text | kept")
        with self.assertRaises(SystemExit):
            figures.fmt("1", "x9")


class Markers(unittest.TestCase):
    def test_kinds(self):
        text = ("a <!--fig:n:c-->38,446 instructions; <!--fig:b:block-->1 | 2<!--/fig--> |\n"
                "| row | <!--fig:r:row-->x | y |\nnext")
        found = {fid: (kind, text[s:e]) for fid, kind, s, e in figures.markers(text)}
        self.assertEqual(found["n"], ("c", "38,446"))
        self.assertEqual(found["b"], ("block", "1 | 2"))
        self.assertEqual(found["r"], ("row", "x | y |"))


class Extraction(unittest.TestCase):
    def test_patterns_and_reductions(self):
        f = RESULTS["figures"]
        self.assertEqual(figures.extract(f["mean"], FOOTPRINT), "38063")
        self.assertEqual(figures.extract(f["size"], FOOTPRINT), "4768")
        runs = "run 1: 2.41 cm\nrun 2: 0.85 cm\nrun 3: 1.50 cm\n"
        self.assertEqual(figures.extract(f["runs"], runs), "2")
        self.assertEqual(figures.extract(dict(f["runs"], reduce="min"), runs), "0.85")
        self.assertEqual(figures.extract(dict(f["runs"], reduce="median"), runs), "1.50")
        self.assertIsNone(figures.extract(f["runs"], "no runs here"))

    def test_tolerances(self):
        self.assertTrue(figures.within({}, "38063", "38063"))
        self.assertFalse(figures.within({}, "38063", "38064"))
        self.assertTrue(figures.within({"tolerance": {"rel": 0.05}}, "100", "104"))
        self.assertFalse(figures.within({"tolerance": {"abs": 1}}, "100", "102"))
        self.assertTrue(figures.within({"tolerance": "none"}, "34", "120"))


class DriftCheck(unittest.TestCase):
    def test_a_changed_fast_figure_fails_and_slow_ones_are_not_required(self):
        with tempfile.TemporaryDirectory() as logs:
            with open(os.path.join(logs, "fw.log"), "w", encoding="utf-8") as out:
                out.write(FOOTPRINT)
            problems, updates = figures.compare(RESULTS, logs, fast_only=True)
            self.assertEqual((problems, updates), ([], {}))
            with open(os.path.join(logs, "fw.log"), "w", encoding="utf-8") as out:
                out.write(FOOTPRINT.replace("mean 38063", "mean 38064"))
            problems, updates = figures.compare(RESULTS, logs, fast_only=True)
            self.assertEqual(updates, {"mean": "38064"})
            self.assertEqual(len(problems), 1)
            self.assertIn("mean: 38064", problems[0])
            os.remove(os.path.join(logs, "fw.log"))
            problems, _ = figures.compare(RESULTS, logs, fast_only=True)
            self.assertEqual(len(problems), 1)
            self.assertIn("no log fw.log", problems[0])


class DocsCheck(unittest.TestCase):
    def test_docs_must_show_the_results_files_values(self):
        with tempfile.TemporaryDirectory() as root:
            doc = os.path.join(root, "README.md")
            old_root, old_docs = figures.ROOT, figures.DOCS
            figures.ROOT, figures.DOCS = root, ["README.md"]
            try:
                body = ("mean <!--fig:mean:c-->38,063; adapter <!--fig:size-->4768 B; "
                        "<!--fig:runs-->2 runs\n")
                with open(doc, "w", encoding="utf-8") as out:
                    out.write(body)
                self.assertEqual(figures.check_docs(RESULTS), [])
                unmeasured = {"producers": RESULTS["producers"],
                              "figures": dict(RESULTS["figures"], runs=dict(RESULTS["figures"]["runs"]))}
                del unmeasured["figures"]["runs"]["measured"]
                self.assertEqual(figures.check_docs(unmeasured),
                                 ["runs: a slow figure without the commit and date it was measured at"])
                with open(doc, "w", encoding="utf-8") as out:
                    out.write(body.replace("38,063", "38,064"))
                errors = figures.check_docs(RESULTS)
                self.assertEqual(len(errors), 1)
                self.assertIn("mean shows '38,064'", errors[0])
                self.assertEqual(figures.write_docs(RESULTS), ["README.md"])
                self.assertEqual(figures.read(doc), body)
            finally:
                figures.ROOT, figures.DOCS = old_root, old_docs


if __name__ == "__main__":
    unittest.main()
