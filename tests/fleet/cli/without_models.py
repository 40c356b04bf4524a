"""`python without_models.py ARGS`: `fleet ARGS` as an install without the `models` extra runs it (the
example-robot-data distribution is not found), for the tests of what such an install still does."""

import sys
from importlib import metadata

_found = metadata.distribution


def distribution(name: str):
    if name.replace("_", "-").lower() == "example-robot-data":
        raise metadata.PackageNotFoundError(name)
    return _found(name)


metadata.distribution = distribution

if __name__ == "__main__":
    from fleet.cli import main

    sys.exit(main(sys.argv[1:]))
