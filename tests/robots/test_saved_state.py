"""Typed state as bytes and back: arrays to the bit, and anything that does not fit its declared type refused in one
line naming the field."""

import msgspec
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from robots.saved_state import SavedState, SavedStateError, pack, unpack, unpack_version


class Inner(SavedState, frozen=True):
    q: np.ndarray
    count: int


class Outer(SavedState, frozen=True):
    inner: Inner
    maybe: np.ndarray | None
    times_s: list[float]


ARRAYS = hnp.arrays(
    st.sampled_from([np.float64, np.float32, np.int64, np.int32, np.bool_]),
    hnp.array_shapes(min_dims=0, max_dims=3, max_side=5),
)


@settings(max_examples=80, deadline=None)
@given(ARRAYS, st.one_of(st.none(), ARRAYS), st.lists(st.floats(allow_nan=False)))
def test_a_state_comes_back_to_the_bit(q, maybe, times_s):
    state = Outer(inner=Inner(q=q, count=3), maybe=maybe, times_s=times_s)
    back = unpack(pack(state), Outer)
    for a, b in ((state.inner.q, back.inner.q), (state.maybe, back.maybe)):
        assert (a is None and b is None) or (a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes())
    assert back.times_s == times_s and pack(back) == pack(state)


def test_a_state_that_does_not_fit_its_type_is_refused_naming_the_field():
    good = msgspec.msgpack.decode(pack(Outer(inner=Inner(q=np.zeros(2), count=1), maybe=None, times_s=[])))
    renamed = {**good, "inner": {"q": good["inner"]["q"], "counted": 1}}
    with pytest.raises(SavedStateError, match=r"not a saved Outer: .*unknown field `counted` - at `\$\.inner`"):
        unpack(msgspec.msgpack.encode(renamed), Outer)
    with pytest.raises(SavedStateError, match=r"\$\.inner\.count"):
        unpack(msgspec.msgpack.encode({**good, "inner": {**good["inner"], "count": "one"}}), Outer)
    with pytest.raises(SavedStateError, match="not an array"):
        unpack(msgspec.msgpack.encode({**good, "maybe": {"dtype": "<f8", "shape": [3], "data": b"\0"}}), Outer)
    with pytest.raises(SavedStateError, match="not a saved Outer"):
        unpack(b"\xc1 not msgpack", Outer)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300))
def test_any_bytes_are_a_state_or_one_error(data):
    try:
        unpack(data, Outer)
    except SavedStateError as exc:
        assert "\n" not in str(exc)


def test_an_object_with_no_saved_form_is_refused():
    class Loose(SavedState):
        thing: object

    with pytest.raises(SavedStateError, match="cannot save Loose: no saved form for type"):
        pack(Loose(thing=set))  # a type object: no state


class Versioned(SavedState, frozen=True):
    version: int
    count: int


def test_a_state_of_another_version_is_refused_in_one_line():
    assert unpack_version(pack(Versioned(version=2, count=1)), Versioned, 2).count == 1
    with pytest.raises(SavedStateError, match=r"^a Versioned of version 1; this clawfleet reads version 2$"):
        unpack_version(pack(Versioned(version=1, count=1)), Versioned, 2)
