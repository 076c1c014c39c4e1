import atexit
import os
import shutil
import tempfile
import textwrap

import pytest

# unit tests evaluate small batches; JIT compilation would only add start-up time
os.environ.setdefault("CASADICAL_JIT", "0")
# compiled functions go to a cache of the test run, never the user's (removed at exit)
os.environ["CASADICAL_CACHE"] = tempfile.mkdtemp(prefix="casadical-test-cache-")
atexit.register(shutil.rmtree, os.environ["CASADICAL_CACHE"], ignore_errors=True)


@pytest.fixture(autouse=True)
def _background_compiles_end_with_the_test():
    """A test that compiled quickly (casadical.model._jitcache) ends as a process would: the optimised compiles
    it started in the background are waited for and kept in the cache they were started for."""
    yield
    from casadical.model import _jitcache as jitcache

    jitcache.finish(kill=False)


@pytest.fixture
def write(tmp_path):
    """Write a text file (dedented) into tmp_path and return its path."""
    def _write(name: str, text: str) -> str:
        p = tmp_path / name
        p.write_text(textwrap.dedent(text).lstrip())
        return str(p)
    return _write
