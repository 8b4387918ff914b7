# SPDX-License-Identifier: GPL-3.0-or-later
"""The source layout the README describes is the one on disk: every file of the logic library is
named in the README's "How it works" section (and every name there exists), every stage file has
its own test file, and no logic source file grows past 800 lines."""
import os
import re
import sys
import unittest

SOURCE = os.environ.get("FEMESHER_SOURCE_DIR") or os.path.join(os.path.dirname(__file__), "..", "..")
LOGIC = os.path.join(SOURCE, "FEMesherLogic", "femesher")


def logic_modules():
    """'Pipeline', 'io/MeshIO', 'stages/internal/LocalDelaunayBuilder', ... (no extension)."""
    names = set()
    for root, _, files in os.walk(LOGIC):
        for f in files:
            m = re.match(r"(.+?)\.(cxx|h|h\.in)$", f)
            if m:
                rel = os.path.relpath(os.path.join(root, m.group(1)), LOGIC)
                names.add(rel.replace(os.sep, "/"))
    return names


def how_it_works():
    with open(os.path.join(SOURCE, "README.md"), encoding="utf-8") as f:
        text = f.read()
    start = text.index("## How it works")
    end = text.index("\n## ", start + 1)
    return text[start:end]


class SourceLayout(unittest.TestCase):
    def test_every_logic_file_is_in_the_readme(self):
        section = how_it_works()
        named = set(re.findall(r"`([A-Za-z/]+)`", section))
        missing = []
        for module in sorted(logic_modules()):
            base = module.split("/")[-1]
            if module not in named and base not in named:
                missing.append(module)
        self.assertEqual(missing, [], "README 'How it works' does not name these files")

    def test_every_file_the_readme_names_exists(self):
        section = how_it_works()
        modules = logic_modules()
        for ref in re.findall(r"`((?:stages|io)/[A-Za-z/]+)`", section):
            self.assertIn(ref, modules, "README names %s, which is not in FEMesherLogic" % ref)

    def test_every_stage_file_has_its_test_file(self):
        stages = os.path.join(LOGIC, "stages")
        tests = os.path.join(SOURCE, "Testing", "Logic")
        for f in sorted(os.listdir(stages)):
            if f.endswith(".cxx"):
                test = "test_" + f
                self.assertTrue(os.path.exists(os.path.join(tests, test)),
                                "stages/%s has no Testing/Logic/%s" % (f, test))

    def test_no_logic_source_over_800_lines(self):
        for root, _, files in os.walk(LOGIC):
            for f in files:
                if f.endswith(".cxx"):
                    path = os.path.join(root, f)
                    with open(path, encoding="utf-8") as fh:
                        n = sum(1 for _ in fh)
                    self.assertLessEqual(n, 800, "%s has %d lines" % (os.path.relpath(path, SOURCE), n))


if __name__ == "__main__":
    result = unittest.main(exit=False, verbosity=2).result
    sys.exit(0 if result.wasSuccessful() else 1)
