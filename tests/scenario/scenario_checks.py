"""Shared by the scenario tests written in Python (tests/scenario/*/check_*.py): named checks that
print `ok` / `FAIL` lines and end the test with exit status 1 when any failed."""
import sys


class Checks:
    def __init__(self):
        self.failures = []

    def __call__(self, ok, what):
        print(('ok   ' if ok else 'FAIL ') + what)
        if not ok:
            self.failures.append(what)

    def finish(self):
        if self.failures:
            print(f'{len(self.failures)} check(s) failed', file=sys.stderr)
            sys.exit(1)
        print('all checks passed')
        sys.exit(0)
