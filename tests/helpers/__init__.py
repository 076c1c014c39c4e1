"""What the tests share: test arms (arms.py), hidden effects and their claims (hidden.py), the next-poses loop
(planning_loop.py) and the command line run in-process (cli.py). Benchmarks import them as ``tests.helpers.*``."""
