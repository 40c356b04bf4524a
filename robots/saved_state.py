"""Typed state as bytes and back: what a component saves (for a run's snapshot) is declared as a msgspec struct,
packed as MessagePack with numpy arrays to the bit.

A state is read back into its declared type only: a field missing, one more, or one of another type is refused
in one line naming it (`$.skill.phase`), so renaming a field can never silently drop what a snapshot holds. What
changes a state's meaning without changing its shape bumps its host's `VERSION`.
"""

from __future__ import annotations

import json
from typing import Any, TypeVar

import msgspec
import numpy as np

S = TypeVar("S", bound=msgspec.Struct)


class SavedStateError(ValueError):
    """A state that cannot be packed, or bytes that are not a state of the type asked for; one line."""


class SavedState(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """The base of every saved state: fields by keyword, none unknown on the way back."""


def _packed(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return {"dtype": obj.dtype.str, "shape": list(obj.shape), "data": obj.tobytes()}
    if isinstance(obj, np.generic):
        return obj.item()
    raise NotImplementedError(f"no saved form for {type(obj).__name__}")


def _unpacked(kind: type, obj: Any) -> Any:
    if kind is np.ndarray and isinstance(obj, dict) and set(obj) == {"dtype", "shape", "data"}:
        try:
            return np.frombuffer(obj["data"], dtype=np.dtype(obj["dtype"])).reshape(obj["shape"]).copy()
        except (TypeError, ValueError) as exc:
            raise ValueError(f"not an array: {exc}") from None
    raise NotImplementedError(f"no saved form for {kind}")


_ENCODER = msgspec.msgpack.Encoder(enc_hook=_packed)


def pack(state: msgspec.Struct) -> bytes:
    """`state` as MessagePack bytes."""
    try:
        return _ENCODER.encode(state)
    except (NotImplementedError, TypeError, OverflowError) as exc:
        raise SavedStateError(f"cannot save {type(state).__name__}: {exc}") from None


def unpack(data: bytes, kind: type[S]) -> S:
    """Bytes from `pack` as a `kind`; anything else is a `SavedStateError` naming the field at fault."""
    try:
        return msgspec.msgpack.decode(data, type=kind, dec_hook=_unpacked)
    except (msgspec.DecodeError, msgspec.ValidationError, ValueError, TypeError) as exc:
        raise SavedStateError(f"not a saved {kind.__name__}: {exc}") from None


def unpack_version(data: bytes, kind: type[S], version: int) -> S:
    """`unpack`, and the state's own `version` must be `version` (a host's state says which it is)."""
    state = unpack(data, kind)
    if state.version != version:
        raise SavedStateError(f"a {kind.__name__} of version {state.version}; this clawfleet reads version {version}")
    return state


BIT_GENERATORS = ("PCG64", "PCG64DXSM", "MT19937", "Philox", "SFC64")


def generator_state(rng: np.random.Generator) -> str:
    """A numpy generator's exact state as JSON (its 128-bit integers are more than MessagePack holds)."""
    return json.dumps(rng.bit_generator.state)


def generator_of(state: str) -> np.random.Generator:
    """A generator standing where `generator_state` saw one."""
    fields = json.loads(state)
    if fields.get("bit_generator") not in BIT_GENERATORS:
        raise SavedStateError(f"not a saved random generator: {fields.get('bit_generator')!r}")
    bit_generator = getattr(np.random, fields["bit_generator"])()
    bit_generator.state = fields
    return np.random.Generator(bit_generator)
