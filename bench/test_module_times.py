"""Each test module's time in a run of the suite, as a markdown table (tests/README.md keeps one):
the sum of its tests' setup, call and teardown times from pytest's JUnit XML and the number of its
tests, slowest first. (Workers run modules side by side: the sum over modules is about twice the
run's wall time on two workers.)

    PYTEST_ADDOPTS=--junitxml=/tmp/junit.xml make test
    .venv/bin/python bench/test_module_times.py /tmp/junit.xml
"""

import sys
import xml.etree.ElementTree as ET
from collections import defaultdict


def main(path: str) -> None:
    seconds: dict[str, float] = defaultdict(float)
    tests: dict[str, int] = defaultdict(int)
    for case in ET.parse(path).getroot().iter("testcase"):
        parts = case.get("classname", "").split(".")  # tests.test_x[.Class]
        module = next((p for p in parts if p.startswith("test_")), parts[-1]) + ".py"
        seconds[module] += float(case.get("time", 0))
        tests[module] += 1
    total = sum(seconds.values())
    print("| module | tests | seconds | share |")
    print("|---|---|---|---|")
    for module in sorted(seconds, key=seconds.get, reverse=True):
        print(f"| {module} | {tests[module]} | {seconds[module]:.0f} | "
              f"{seconds[module] / total:.1%} |")  # fmt: skip
    print(f"| all ({len(seconds)} modules) | {sum(tests.values())} | {total:.0f} | |")


if __name__ == "__main__":
    main(sys.argv[1])
