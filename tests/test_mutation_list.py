"""scripts/mutate.py's planted bugs still apply to the code as it is.

Each mutation is an exact source edit; when the code it plants a bug in is
rewritten, the edit no longer applies and the harness stops (``--list``).
Four of them had rotted that way unseen, until this test: the list is
checked here, on every run of the suite, not only when the harness runs.
"""

from __future__ import annotations

import pytest

from conftest import load_script


def test_every_mutation_edit_applies_to_the_code():
    mutate = load_script("mutate")
    mutate.check_mutations()


def test_a_rotted_edit_is_reported():
    mutate = load_script("mutate")
    first = mutate.MUTATIONS[0]
    edit = first.edits[0]
    rotted = mutate.Mutation(first.name, first.stage, first.where, first.what,
                             (mutate.Edit(edit.path, edit.old + "no such text", edit.new),), first.quick)
    with pytest.raises(mutate.HarnessError, match="occurs 0 times"):
        mutate.check_mutations((rotted,))
