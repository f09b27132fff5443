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


@pytest.mark.parametrize("kept", [False, True])
def test_prepared_in_the_background_is_the_program_called(tmp_path, kept):
    """``prepare`` compiles in a thread; the first call with inputs of that shape uses it
    (no second program), returns what a plain call returns, and an input of another shape
    still gets its own program."""
    t = _make(tmp_path if kept else None)
    state = {"s": np.zeros(4, np.float32)}
    t.prepare(state, np.zeros(4, np.float32))
    assert t.n_programs == 1
    out = _call(t)
    np.testing.assert_array_equal(out[0]["s"], 2.0 * np.arange(4, dtype=np.float32))
    assert out[1:] == (6.0, 4) and t.n_programs == 1
    t({"s": np.zeros(5, np.float32)}, np.ones(5, np.float32))
    assert t.n_programs == 2


def test_a_failed_preparation_raises_at_the_first_call():
    def bad(state, x):
        raise ValueError("no such program")

    t = Traced(bad, "bad", None, static="", out_like=_like)
    t.prepare({"s": np.zeros(2, np.float32)}, np.zeros(2, np.float32))
    with pytest.raises(ValueError, match="no such program"):
        t({"s": np.zeros(2, np.float32)}, np.zeros(2, np.float32))
