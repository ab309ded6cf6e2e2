"""What the equation compiler says about a model it cannot compile: one line through
``deltafmi build`` naming the model's file:line, the equations and the unknowns."""
import re
import subprocess
import sys

import pytest

HEAD = """\
from deltafmi.component import Input, Output, Parameter
from deltafmi.runtime.equations import EquationComponent, Real, der


class Bad(EquationComponent):
    \"\"\"A model with a mistake.\"\"\"
    k = Parameter(1.0)
    u = Input(0.0)
    x = Real(1.0)
    a = Output()
    b = Output()

    def equations(self):
        return [der(self.x) == -self.k * self.x,
"""
CASES = {
    "over-determined": ("self.a == self.x, self.b == self.x, self.b == 2.0 * self.x]",
                        r"bad.py:15: b = \(2.0\*x\): over-determined: it constrains \[x\], which the other "
                        r"equations determine already"),
    "under-determined": ("self.a == self.x]",
                         r"Bad: under-determined: 2 equations for 3 unknowns; no equation determines \[b\]"),
    "structurally singular": ("self.a + self.x == 1.0, 2.0 * self.a == self.x]",
                              r"Bad: structurally singular: the 2 equations \[bad.py:15: \(a\+x\) = 1.0; bad.py:15: "
                              r"\(2.0\*a\) = x\] determine only the 1 unknowns \[a\]; no equation is left for \[b\]"),
    "der of an input": ("self.a == der(self.u), self.b == self.x]",
                        r"bad.py:15: der\(u\) of an input: inputs are not differentiated"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_build_names_the_problem_in_one_line(case, tmp_path):
    tail, message = CASES[case]
    (tmp_path / "bad.py").write_text(HEAD + "                " + tail + "\n")
    result = subprocess.run([sys.executable, "-c", "from deltafmi.apps.cli import main; main()", "build", "bad.py",
                             "-o", "bad.fmu"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert re.search(message, lines[0]), lines[0]
