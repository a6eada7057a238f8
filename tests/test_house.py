"""House rules of the packages (issue 36): no module above 500 lines, no function above 80 lines without the
reason written at its top (a comment `# Over 80 lines ...` among the first lines of its body)."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("scenes", "wildgen", "unips", "validate", "orchestrate")
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 80
REASON = "# Over 80 lines"


def _long_functions_without_reason(source: str) -> list[str]:
    lines = source.splitlines()
    bad = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            length = node.end_lineno - node.lineno + 1
            top = lines[node.body[0].lineno - 1:node.body[0].end_lineno + 3]  # the first statement and below it
            if length > MAX_FUNCTION_LINES and not any(line.strip().startswith(REASON) for line in top):
                bad.append(f"{node.name} ({length} lines)")
    return bad


def test_no_module_above_500_lines_and_no_long_function_without_a_reason():
    files = [p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))]
    assert len(files) > 100  # the packages are seen
    big = {str(p.relative_to(ROOT)): n for p in files if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not big, f"modules above {MAX_MODULE_LINES} lines: {big}"
    long = {str(p.relative_to(ROOT)): f for p in files if (f := _long_functions_without_reason(p.read_text()))}
    assert not long, f"functions above {MAX_FUNCTION_LINES} lines without a reason at their top: {long}"


def test_the_function_rule_can_fail():
    body = "\n".join(f"    x{i} = {i}" for i in range(90))
    assert _long_functions_without_reason(f"def f():\n    \"\"\"Doc.\"\"\"\n{body}\n") == ["f (92 lines)"]
    reason = "    # Over 80 lines on purpose: a test.\n"
    assert _long_functions_without_reason(f"def f():\n    \"\"\"Doc.\"\"\"\n{reason}{body}\n") == []
