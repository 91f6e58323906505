"""The module-circle check on crates made for the test (make check-circles runs it)."""
import os
import subprocess
import sys
import tempfile
import unittest

SCRIPT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "module_circles.py")


def run(root, baseline, *args):
    env = dict(os.environ, MODULE_CIRCLES_ROOT=root, MODULE_CIRCLES_BASELINE=baseline)
    return subprocess.run([sys.executable, SCRIPT, *args], capture_output=True, text=True, env=env)


class ModuleCircles(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.TemporaryDirectory()
        self.root = self.dir.name
        self.baseline = os.path.join(self.root, "baseline")
        with open(self.baseline, "w") as f:
            f.write("# nothing allowed\n")

    def tearDown(self):
        self.dir.cleanup()

    def crate(self, name, files):
        for rel, text in {"Cargo.toml": f'[package]\nname = "{name}"\n', **files}.items():
            p = os.path.join(self.root, name, rel)
            os.makedirs(os.path.dirname(p), exist_ok=True)
            with open(p, "w") as f:
                f.write(text)

    def test_a_circle_is_found_through_use_groups_and_paths(self):
        self.crate("x", {
            "src/lib.rs": "pub mod a; pub mod b; pub mod c;\n",
            "src/a.rs": "use crate::{b::B, c};\npub struct A;\n",
            "src/b/mod.rs": "pub mod inner;\npub struct B;\n",
            "src/b/inner.rs": "fn f() -> crate::a::A { crate::a::A }\n",
            "src/c.rs": "pub struct C;\n",
        })
        r = run(self.root, self.baseline)
        self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
        self.assertIn("x: a b", r.stderr)
        self.assertEqual(run(self.root, self.baseline, "--print").stdout, "x: a b\n")

    def test_comments_strings_and_tests_are_no_imports(self):
        self.crate("y", {
            "src/lib.rs": "pub mod a; pub mod b;\n",
            "src/a.rs": "use crate::b::B;\npub struct A;\n",
            "src/b.rs": '/// See [`crate::a::A`].\n// crate::a\n/* crate::a */\n'
                        'pub struct B;\nfn f() -> &\'static str { "crate::a::A" }\n'
                        '#[cfg(test)]\nmod tests {\n    use crate::a::A;\n    fn g() { let _ = A; }\n}\n',
        })
        r = run(self.root, self.baseline)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)

    def test_the_baseline_allows_its_circle_but_not_a_larger_one(self):
        files = {
            "src/lib.rs": "pub mod a; pub mod b; pub mod c;\n",
            "src/a.rs": "use crate::b::B;\npub struct A;\n",
            "src/b.rs": "use crate::a::A;\npub struct B;\n",
            "src/c.rs": "pub struct C;\n",
        }
        self.crate("z", files)
        with open(self.baseline, "w") as f:
            f.write("z: a b\n")
        self.assertEqual(run(self.root, self.baseline).returncode, 0)
        # c joins the circle: refused although a and b were allowed.
        self.crate("z", {"src/c.rs": "use crate::a::A;\npub struct C;\n", "src/b.rs": "use crate::{a::A, c::C};\npub struct B;\n"})
        r = run(self.root, self.baseline)
        self.assertEqual(r.returncode, 1)
        self.assertIn("z: a b c", r.stderr)

    def test_a_circle_gone_asks_for_the_baseline_to_be_tightened(self):
        self.crate("w", {"src/lib.rs": "pub mod a;\n", "src/a.rs": "pub struct A;\n"})
        with open(self.baseline, "w") as f:
            f.write("w: a b\n")
        r = run(self.root, self.baseline)
        self.assertEqual(r.returncode, 0)
        self.assertIn("tighten", r.stdout)


if __name__ == "__main__":
    unittest.main()
