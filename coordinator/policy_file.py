"""A trained choice policy as a plain file: an exported torch program (`torch.export`, a `.pt2` archive:
TorchScript's successor, which torch 2.13 deprecates) from an arm's choice features (`CHOICE_FEATURES` float32 values
a row) to one logit per action (`SLOTS + 1`: wait, then each slot), with a header that says what it observes. The
env's trainers write it (`save_policy`); the coordinator's `policy:FILE` allocator reads it (`load_policy`). Torch
comes with the `rl` extra and is imported only here, only when a policy is used.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from coordinator.choice_slots import CHOICE_FEATURES, SLOTS

FORMAT = "clawfleet.choice-policy"
VERSION = 1
HEADER = "clawfleet.json"  # the header's name among the archive's extra files
MAX_ROWS = 4096  # rows (arms) one call may score


class PolicyFileError(ValueError):
    """A policy file that cannot be used; the message is one line and names the file."""


@dataclass(frozen=True)
class PolicyHeader:
    """What a policy file says of itself: its format and version, what it observes, and where it was trained."""

    format: str = FORMAT
    version: int = VERSION
    features: int = CHOICE_FEATURES
    actions: int = SLOTS + 1
    trained_on: str = ""  # free text: scene, load, algorithm, steps


def _torch() -> Any:
    try:
        import torch
    except ImportError:
        raise PolicyFileError("a policy file needs torch: pip install 'clawfleet[rl]'") from None
    return torch


def save_policy(module: Any, path: str | Path, trained_on: str = "") -> Path:
    """Write `module` (a `torch.nn.Module` from a float32 batch of choice features to logits) as a policy file:
    exported for any number of rows, with its header. Returns the path."""
    torch = _torch()
    example = torch.zeros((2, CHOICE_FEATURES), dtype=torch.float32)
    rows = torch.export.Dim("rows", min=1, max=MAX_ROWS)
    program = torch.export.export(module.eval(), (example,), dynamic_shapes=({0: rows},))
    path = Path(path)
    header = json.dumps(PolicyHeader(trained_on=trained_on).__dict__)
    torch.export.save(program, str(path), extra_files={HEADER: header})
    return path


class ChoicePolicy:
    """A loaded policy file: logits for a batch of choice feature rows (one thread: the coordinator's decisions are
    small, and a line's processes share the machine's cores)."""

    def __init__(self, module: Any, header: PolicyHeader, path: Path) -> None:
        self.module, self.header, self.path = module, header, path
        self._torch = _torch()

    def __reduce__(self):
        """Pickled as its file (a run's snapshot): read again where it is read back, so the file must still be
        there (an exported torch program does not pickle)."""
        return (load_policy, (str(self.path),))

    def logits(self, features: np.ndarray) -> np.ndarray:
        """(rows, `SLOTS + 1`) logits for (rows, `CHOICE_FEATURES`) features."""
        with self._torch.no_grad():
            out = self.module(self._torch.from_numpy(np.ascontiguousarray(features, dtype=np.float32)))
        return out.numpy().astype(float)


def load_policy(path: str | Path) -> ChoicePolicy:
    """Read and check a policy file: PolicyFileError (one line, naming the file) for a missing, unreadable or
    foreign file, another format version, or a module whose answer to a probe is not `SLOTS + 1` finite logits."""
    path = Path(path)
    if not path.is_file():
        raise PolicyFileError(f"policy file {path}: no such file")
    torch = _torch()
    torch.set_num_threads(1)
    extra = {HEADER: ""}
    try:
        module = torch.export.load(str(path), extra_files=extra).module()
    except Exception as exc:  # torch says a bad file many ways (RuntimeError, ValueError, zip errors)
        raise PolicyFileError(f"policy file {path}: not an exported torch program ({exc.__class__.__name__})") from None
    header = _header(path, extra[HEADER])
    policy = ChoicePolicy(module, header, path)
    try:
        probe = policy.logits(np.zeros((2, CHOICE_FEATURES), np.float32))
    except Exception as exc:  # the module's own fault: said once, before any line starts
        why = f"{exc}".split("\n")[0]
        raise PolicyFileError(f"policy file {path}: its module fails on choice features: {why}") from None
    if probe.shape != (2, SLOTS + 1) or not np.isfinite(probe).all():
        raise PolicyFileError(
            f"policy file {path}: its module answers {tuple(probe.shape)} for 2 rows, not {SLOTS + 1} finite logits "
            "a row"
        )
    return policy


def _header(path: Path, text: str | bytes) -> PolicyHeader:
    """The file's header, checked against this clawfleet's choice features."""
    try:
        fields = json.loads(text or "null")
        header = PolicyHeader(**fields)
    except (ValueError, TypeError):
        raise PolicyFileError(f"policy file {path}: no clawfleet header (write it with save_policy)") from None
    if header.format != FORMAT or header.version != VERSION:
        raise PolicyFileError(
            f"policy file {path}: format {header.format} v{header.version}; this clawfleet reads {FORMAT} v{VERSION}"
        )
    if (header.features, header.actions) != (CHOICE_FEATURES, SLOTS + 1):
        raise PolicyFileError(
            f"policy file {path}: made for {header.features} features and {header.actions} actions; "
            f"this clawfleet's choices have {CHOICE_FEATURES} and {SLOTS + 1}"
        )
    return header
