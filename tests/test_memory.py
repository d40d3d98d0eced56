"""gyrotherm._memory: glibc's arena limit and malloc_trim, and the daemon's shallow preload.

The two C calls are checked against the C library's own answers (``mallopt`` returns 1 on
success, ``malloc_trim`` 1 when it gave memory back); the preload against the import
order ``python -X importtime`` reports for ``gyrotherm run``.
"""

from __future__ import annotations

import ctypes.util
import os
import re
import subprocess
import sys
import textwrap

import pytest

from gyrotherm import _memory

GLIBC = _memory._glibc() is not None


def _child(code: str, **env: str) -> str:
    base = {k: v for k, v in os.environ.items() if k != "MALLOC_ARENA_MAX"}
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, timeout=60, env={**base, **env}, check=True)
    return done.stdout.strip()


@pytest.mark.skipif(not GLIBC, reason=f"not glibc (C library {ctypes.util.find_library('c')})")
def test_limit_arenas_sets_the_option_unless_the_operator_did() -> None:
    code = """
        from gyrotherm import _memory
        print(_memory.limit_arenas())
    """
    assert _child(code) == "True"
    assert _child(code, MALLOC_ARENA_MAX="4") == "False"  # glibc reads the operator's own


@pytest.mark.skipif(not GLIBC, reason="not glibc")
def test_release_free_heap_returns_freed_pages() -> None:
    # 64 MiB of small blocks freed in the middle of the heap: malloc_trim hands them back
    out = _child("""
        import re
        from gyrotherm import _memory
        def rss_kb():
            return int(re.search(r"VmRSS:\\s+(\\d+)", open("/proc/self/status").read())[1])
        keep = []
        blocks = [bytearray(4000) for _ in range(16000)]
        keep.append(bytearray(4000))  # a live block above them: no plain top-of-heap shrink
        del blocks
        before = rss_kb()
        gave = _memory.release_free_heap()
        print(gave, before - rss_kb())
    """)
    gave, freed_kb = out.split()
    assert gave == "True"
    assert int(freed_kb) > 16_000  # most of the 62 MB left the process


def test_without_glibc_both_calls_are_no_ops(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(_memory, "_LIBC", None)
    monkeypatch.setattr(_memory, "_LOOKED", True)
    monkeypatch.delenv("MALLOC_ARENA_MAX", raising=False)
    assert _memory.limit_arenas() is False
    assert _memory.release_free_heap() is False


def test_gyrotherm_run_imports_its_dependencies_before_its_own_modules(tmp_path) -> None:
    """numpy, zenoh, python-can, cantools and msgpack load first, near the bottom of the stack
    (cli._run.preload): imported deep inside gyrotherm's imports, CPython 3.11 maps and
    unmaps a 16 KiB frame chunk per call in their import-time loops (≈ 1 400 times)."""
    done = subprocess.run([sys.executable, "-X", "importtime", "-m", "gyrotherm", "run",
                           "--config", str(tmp_path / "missing.toml")],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert "missing.toml" in done.stderr  # it got as far as reading the config
    order: list[tuple[str, int]] = []
    for line in done.stderr.splitlines():
        m = re.match(r"import time:\s+\d+ \|\s+\d+ \|( *)(\S+)$", line)
        if m:
            order.append((m[2], len(m[1])))
    names = [n for n, _ in order]
    first_own = min(i for i, n in enumerate(names)
                    if n.startswith("gyrotherm.") and n not in (
                        "gyrotherm._memory", "gyrotherm._errors") and not n.startswith(
                        "gyrotherm.cli"))
    depth = dict(order)
    for dep in ("numpy", "zenoh", "can", "cantools", "msgpack"):
        assert dep in names, dep
        assert names.index(dep) < first_own, f"{dep} imported after gyrotherm's own modules"
        # importtime indents a module by 2 per enclosing import: the console entry imports
        # gyrotherm.cli (0), which the preload does not sit under
        assert depth[dep] <= 2, f"{dep} imported at nesting {depth[dep] // 2}"
