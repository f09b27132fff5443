"""``robot.traced.Traced``: the step exported once, read back by a later process (here: a new
instance) without tracing, the same results; a damaged file is traced again and rewritten."""

import jax.numpy as jnp
import numpy as np
import pytest

from mfcl_jax.robot.traced import Traced


def _f(state, x, scale):
    return {"s": state["s"] + x * scale}, jnp.sum(x), x.shape[0]


def _like(state, x):
    return {"s": 0}, 0, 0


def _make(folder):
    return Traced(lambda s, x: _f(s, x, 2.0), "t", folder, static="scale=2", out_like=_like,
                  donate_argnums=(0,))  # fmt: skip


def _call(t):
    state = {"s": np.zeros(4, np.float32)}
    out = t(state, np.arange(4, dtype=np.float32))
    return {"s": np.asarray(out[0]["s"])}, float(out[1]), int(out[2])


def test_kept_program_read_back_without_tracing(tmp_path, monkeypatch):
    want = _call(_make(None))  # a plain jit
    first = _call(_make(tmp_path))
    (kept,) = (tmp_path / "traced").glob("t-*.jaxexport")
    np.testing.assert_array_equal(first[0]["s"], want[0]["s"])
    assert first[1:] == want[1:]
    # a new instance (a new process) reads the file and never traces the function
    monkeypatch.setattr(Traced, "_export", lambda *a: pytest.fail("traced again"))
    again = _call(_make(tmp_path))
    np.testing.assert_array_equal(again[0]["s"], want[0]["s"])
    assert again[1:] == want[1:]
    monkeypatch.undo()
    # a damaged file is traced again and rewritten; the answer is the same
    kept.write_bytes(b"not a program")
    fixed = _call(_make(tmp_path))
    np.testing.assert_array_equal(fixed[0]["s"], want[0]["s"])
    assert kept.read_bytes() != b"not a program"
