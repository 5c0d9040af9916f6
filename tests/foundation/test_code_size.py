"""Issue 26's size rule, kept: no module over 600 lines and no function over 100 lines unless
a ``# size: <why>`` comment says why it cannot be split (tools/code_size.py)."""

import subprocess
import sys

from ..helpers import REPO


def test_no_module_or_function_over_the_limits_without_a_reason():
    r = subprocess.run([sys.executable, str(REPO / "tools" / "code_size.py")], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "0 without a '# size:' reason" in r.stdout


def test_the_checker_sees_a_long_function(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(120))
    (tmp_path / "long.py").write_text(f"def f():\n{body}\n")
    r = subprocess.run([sys.executable, str(REPO / "tools" / "code_size.py"), str(tmp_path)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and "f() line 1" in r.stdout, r.stdout
