#!/usr/bin/env python3
"""
Print the observed convergence order of each seed integrator, body and wrench.

The same measurement as ``test/test_integrator_convergence.py`` (every registered kernel
at dt and dt/2 against scipy's DOP853 at rtol 1e-13), printed as a table: the observed order
log2(error(dt) / error(dt/2)) of the whole state error, per method (rows) and per body and
wrench (columns), and the smallest and largest over each row.

Usage: ``.venv/bin/python benchmarks/convergence_orders.py`` (about a minute).
"""

from pathlib import Path
import sys

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'test'))

import test_integrator_convergence as convergence  # noqa: E402  (after the path set-up)


def main(argv=None):
    """Print the table; return 0."""
    import argparse
    argparse.ArgumentParser(description=__doc__.strip().splitlines()[0],
                            epilog='Usage: .venv/bin/python benchmarks/convergence_orders.py '
                                   '(no options; about a minute)').parse_args(argv)
    columns = [(body, wrench) for body in sorted(convergence.BODIES)
               for wrench in convergence.WRENCHES]
    print('observed order (whole state error) per body and wrench; nominal order first')
    for name, (order, steps) in sorted(convergence.METHODS.items()):
        observed = []
        for body, wrench in columns:
            coarse, fine = convergence._errors(name, body, wrench, steps)
            observed.append(convergence._order(coarse['total'], fine['total']))
        print(f'{name:12s} nominal {order}: observed {min(observed):.2f} to {max(observed):.2f}'
              f' over {len(columns)} (body, wrench) pairs')
        for (body, wrench), value in zip(columns, observed):
            print(f'    {body:18s} {wrench:24s} {value:.3f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
