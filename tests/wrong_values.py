"""Values a declaration's fields should never hold, and a way to put one anywhere in a declaration's data: what the
property tests over whole schemas (scene files, robot files) draw from."""

from hypothesis import strategies as st


def leaves(node: object, path: tuple = ()) -> list[tuple]:
    """The path of every value in a declaration's data that is not itself a list or a mapping."""
    if isinstance(node, dict):
        return [p for k, v in node.items() for p in leaves(v, (*path, k))]
    if isinstance(node, list):
        return [p for i, v in enumerate(node) for p in leaves(v, (*path, i))]
    return [path]


def with_value(data: object, path: tuple, value: object) -> object:
    if not path:
        return value
    copy = dict(data) if isinstance(data, dict) else list(data)
    copy[path[0]] = value if len(path) == 1 else with_value(data[path[0]], path[1:], value)
    return copy


WRONG = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, -1, 1, 2**70, -(2**70), 1e300, -1e300, 5e-324, 0.0, -0.0]),
    st.integers(min_value=-(2**80), max_value=2**80),
    st.text(max_size=12),
    st.none(),
    st.booleans(),
    st.lists(st.integers(min_value=-5, max_value=5), max_size=4),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
)
