"""Policy files: what a trainer writes, the coordinator reads back to the same logits; a file it cannot use is refused
in one line that names it, before any line starts."""

import json

import numpy as np
import pytest
import torch

from coordinator.allocator_plugins import AllocatorError, check_allocator
from coordinator.choice_slots import CHOICE_FEATURES, SLOTS
from coordinator.policy_file import HEADER, PolicyFileError, load_policy, save_policy
from tests.coordinator.choice_policies import policy_file, random_policy


def test_a_saved_policy_reads_back_to_the_same_logits(tmp_path):
    module = random_policy(seed=3)
    policy = load_policy(save_policy(module, tmp_path / "p.pt2", trained_on="test"))
    features = np.random.default_rng(0).normal(size=(7, CHOICE_FEATURES)).astype(np.float32)
    with torch.no_grad():
        expected = module(torch.from_numpy(features)).numpy()
    np.testing.assert_allclose(policy.logits(features), expected, rtol=1e-6)
    assert policy.header.trained_on == "test"


def test_a_loaded_policy_pickles_as_its_file_and_reads_back_to_the_same_logits(tmp_path):
    """A run's snapshot holds the coordinator's allocator: a policy goes in as its file, read again on restore."""
    import pickle

    policy = load_policy(save_policy(random_policy(seed=4), tmp_path / "p.pt2", trained_on="test"))
    again = pickle.loads(pickle.dumps(policy))
    features = np.random.default_rng(1).normal(size=(5, CHOICE_FEATURES)).astype(np.float32)
    np.testing.assert_array_equal(again.logits(features), policy.logits(features))
    assert len(pickle.dumps(policy)) < 1000, "the file's path, not the program"


def test_the_allocator_spec_names_the_file_by_its_absolute_path(tmp_path, monkeypatch):
    policy_file(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert check_allocator("policy:random_0.pt2") == f"policy:{tmp_path / 'random_0.pt2'}"


def _exported(module, path, header=None):
    """`module` exported as torch does it, with `header` (a dict) if given: a file clawfleet did not write."""
    program = torch.export.export(module, (torch.zeros(2, CHOICE_FEATURES),))
    torch.export.save(program, str(path), extra_files={HEADER: json.dumps(header)} if header else None)


def _foreign(path):
    _exported(random_policy(), path)


def _other_version(path):
    _exported(random_policy(), path, {"format": "clawfleet.choice-policy", "version": 99})


def _other_size(path):
    _exported(torch.nn.Linear(CHOICE_FEATURES, 3), path, {"actions": SLOTS + 1})


def _nan(path):
    module = random_policy()
    with torch.no_grad():
        module[2].bias[1] = float("nan")
    save_policy(module, path)


def _truncated(path):
    save_policy(random_policy(), path)
    path.write_bytes(path.read_bytes()[:500])


@pytest.mark.parametrize(
    ("make", "says"),
    [
        (None, "no such file"),
        (lambda p: p.write_bytes(b"not a model at all"), "not an exported torch program"),
        (_truncated, "not an exported torch program"),
        (_foreign, "no clawfleet header"),
        (_other_version, "v99; this clawfleet reads clawfleet.choice-policy v1"),
        (_other_size, f"not {SLOTS + 1} finite logits a row"),
        (_nan, "finite logits"),
    ],
)
def test_a_file_that_cannot_be_used_is_refused_in_one_line_naming_it(tmp_path, make, says):
    path = tmp_path / "policy.pt2"
    if make is not None:
        make(path)
    with pytest.raises(PolicyFileError, match=says) as refused:
        load_policy(path)
    assert str(path) in str(refused.value) and "\n" not in str(refused.value)
    with pytest.raises(AllocatorError, match=says):
        check_allocator(f"policy:{path}")
