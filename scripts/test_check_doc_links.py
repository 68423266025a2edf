#!/usr/bin/env python3
"""Tests of scripts/check-doc-links on a small rendered-documentation tree written here:
each kind of bad link is reported (and only the bad ones), a clean tree passes.

    python3 scripts/test_check_doc_links.py
"""

import importlib.machinery
import importlib.util
import tempfile
import unittest
from pathlib import Path

HERE = Path(__file__).resolve().parent
loader = importlib.machinery.SourceFileLoader("check_doc_links", str(HERE / "check-doc-links"))
spec = importlib.util.spec_from_loader(loader.name, loader)
links = importlib.util.module_from_spec(spec)
loader.exec_module(links)

PACKAGE_FILES = {"Cargo.toml", "README.md", "CHANGELOG.md", "docs/tuning.md", "src/lib.rs"}
SOURCE = "https://docs.rs/crate/ctrl-adapt/{}/source/{}"


def page(*hrefs, ids=()):
    anchors = "".join(f'<a href="{h}">x</a>' for h in hrefs)
    targets = "".join(f'<h2 id="{i}">t</h2>' for i in ids)
    return f"<html><body>{targets}{anchors}</body></html>"


class CheckDocLinks(unittest.TestCase):
    def tree(self, index_html):
        root = Path(self.enterContext(tempfile.TemporaryDirectory()))
        (root / "ctrl_adapt" / "optimizer").mkdir(parents=True)
        (root / "src" / "ctrl_adapt").mkdir(parents=True)
        (root / "ctrl_adapt" / "index.html").write_text(index_html)
        (root / "ctrl_adapt" / "optimizer" / "index.html").write_text(
            page("../index.html", ids=["impl-Clone-for-Bounds%3CN%3E"]))
        (root / "src" / "ctrl_adapt" / "lib.rs.html").write_text(page())
        return root

    def bad(self, index_html, version="0.2.0"):
        root = self.tree(index_html)
        return [(p, h) for p, h, _ in links.check(root, PACKAGE_FILES, version)]

    def test_good_links_pass(self):
        html = page(
            "optimizer/index.html",
            "optimizer/",  # a directory stands for its index.html
            "optimizer/index.html#impl-Clone-for-Bounds%3CN%3E",
            "#figures",
            "../src/ctrl_adapt/lib.rs.html#1-40",  # source line ranges: resolved by script
            SOURCE.format("0.2.0", "docs/tuning.md"),
            SOURCE.format("0.2.0", "CHANGELOG.md"),
            "https://docs.rs/crate/heapless/0.9.1/source/README.md",  # another crate's
            "https://example.org/paper.pdf",
            ids=["figures"],
        )
        self.assertEqual(self.bad(html), [])

    def test_repository_relative_links_fail(self):
        # What the README's inline links to repository files rendered as on docs.rs.
        html = page("docs/tuning.md", "CHANGELOG.md", "experiments/findings/README.md")
        self.assertEqual(self.bad(html), [
            ("ctrl_adapt/index.html", "docs/tuning.md"),
            ("ctrl_adapt/index.html", "CHANGELOG.md"),
            ("ctrl_adapt/index.html", "experiments/findings/README.md"),
        ])

    def test_missing_fragments_fail(self):
        html = page("#nowhere", "optimizer/index.html#impl-Nothing", ids=["figures"])
        self.assertEqual(self.bad(html), [
            ("ctrl_adapt/index.html", "#nowhere"),
            ("ctrl_adapt/index.html", "optimizer/index.html#impl-Nothing"),
        ])

    def test_docs_rs_links_to_unpublished_files_or_other_versions_fail(self):
        findings = SOURCE.format("0.2.0", "experiments/findings/README.md")
        old = SOURCE.format("0.1.0", "docs/tuning.md")
        self.assertEqual(self.bad(page(findings, old)), [
            ("ctrl_adapt/index.html", findings),
            ("ctrl_adapt/index.html", old),
        ])

    def test_links_out_of_the_documentation_fail(self):
        self.assertEqual(self.bad(page("../../README.md")),
                         [("ctrl_adapt/index.html", "../../README.md")])

    def test_bad_links_on_inner_pages_are_found(self):
        root = self.tree(page())
        (root / "ctrl_adapt" / "optimizer" / "index.html").write_text(page("../docs/safety.md"))
        bad = links.check(root, PACKAGE_FILES, "0.2.0")
        self.assertEqual([(p, h) for p, h, _ in bad],
                         [("ctrl_adapt/optimizer/index.html", "../docs/safety.md")])

    def test_no_rendered_documentation_fails(self):
        empty = Path(self.enterContext(tempfile.TemporaryDirectory()))
        self.assertEqual(len(links.check(empty, PACKAGE_FILES, "0.2.0")), 1)


if __name__ == "__main__":
    unittest.main()
