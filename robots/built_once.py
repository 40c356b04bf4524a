"""Objects built from fixed inputs and never changed after (a robot's kinematic model, an arm's collision frames or
its top-down IK where it stands): pickled as those inputs, and read back as the object this process already built
from the same inputs, else built anew.

A run's snapshot holds every arm's models several times over (the coordinator's guard and reach checks, each
controller's skill); written as their inputs, a state is a tenth of the size, and reading one back rebuilds nothing
the process has. The inputs are recognised by identity (`id` of the robot's declaration, bytes of a placement), so
an object is found again only where the process holds the very same declaration: a registered robot's.
"""

from __future__ import annotations

import weakref
from collections.abc import Hashable

_BUILT: weakref.WeakValueDictionary = weakref.WeakValueDictionary()


class BuiltOnce:
    """Mixed into a class whose instances are fixed once built: `_built_from(args, key)` at the end of `__init__`
    (`args`: what to call the class with again; `key`: those inputs as a hashable value, each object it names by
    `id` held by the instance, so that no id is reused while the instance lives)."""

    _built_args: tuple = ()

    def _built_from(self, args: tuple, key: Hashable) -> None:
        self._built_args = args
        _BUILT.setdefault((type(self).__qualname__, key), self)

    @classmethod
    def built_key(cls, *args) -> Hashable:
        """The key `__init__` gives `_built_from` for these arguments."""
        raise NotImplementedError

    def __reduce__(self):
        return (built, (type(self), self._built_args))


def built(cls: type[BuiltOnce], args: tuple) -> BuiltOnce:
    """The instance of `cls` this process built from `args`, or one built now."""
    found = _BUILT.get((cls.__qualname__, cls.built_key(*args)))
    return found if found is not None else cls(*args)
