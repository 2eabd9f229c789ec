"""core.runs.stages: a stage is skipped exactly when it and the stages before it are unchanged."""

import pytest

from core.runs.stages import Stages


def _pipeline(folder, calls, *, a=1, b=2, from_stage=None, reuse=None):
    st = Stages(folder, ["first", "second"], from_stage=from_stage, reuse=reuse)

    def first(x):
        calls.append("first")
        return x * 10

    def second(y, z):
        calls.append("second")
        return y + z

    x = st.run("first", first, a, depends={"a": a})
    return st.run("second", second, x, b, depends={"b": b}), st


def test_skips_unchanged_and_reruns_what_changed(tmp_path):
    calls = []
    assert _pipeline(tmp_path, calls)[0] == 12 and calls == ["first", "second"]
    calls.clear()
    assert _pipeline(tmp_path, calls)[0] == 12 and calls == []
    assert _pipeline(tmp_path, calls, b=5)[0] == 15 and calls == ["second"]
    calls.clear()
    assert _pipeline(tmp_path, calls, a=2, b=5)[0] == 25 and calls == ["first", "second"]
    calls.clear()
    _, st = _pipeline(tmp_path, calls, a=2, b=5, from_stage="second")
    assert calls == ["second"] and st.ran == ["second"] and st.skipped == ["first"]


def test_reuse_reads_an_earlier_folder_and_corrupt_caches_are_recomputed(tmp_path):
    calls = []
    _pipeline(tmp_path / "old", calls)
    calls.clear()
    assert _pipeline(tmp_path / "new", calls, reuse=tmp_path / "old")[0] == 12 and calls == []
    (tmp_path / "new" / "stages" / "second.pkl").write_bytes(b"not a pickle")
    assert _pipeline(tmp_path / "new", calls)[0] == 12 and calls == ["second"]
    with pytest.raises(ValueError, match="from_stage"):
        Stages(tmp_path, ["first"], from_stage="third")


def test_a_cache_not_signed_by_this_user_is_never_unpickled(tmp_path):
    import json
    import pickle

    calls = []
    _pipeline(tmp_path, calls)
    calls.clear()

    class Boom:
        def __reduce__(self):  # would run on unpickling
            return (calls.append, ("unpickled!",))

    pkl = tmp_path / "stages" / "first.pkl"
    pkl.write_bytes(pickle.dumps(Boom()))  # same key in first.json, foreign bytes
    meta = json.loads((tmp_path / "stages" / "first.json").read_text())
    assert meta["hmac"]
    assert _pipeline(tmp_path, calls)[0] == 12
    assert "unpickled!" not in calls and calls == ["first"]  # recomputed, not loaded
