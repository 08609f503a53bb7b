"""Messages that name request keys: each front end words the keys, and nothing else in the message."""

import pickle

from prs3_post.core.errors import InputError, Prs3Warning, ReachError


def _flag(key: str) -> str:
    return "--" + key.replace("_", "-").removeprefix("setup.")


def test_a_message_names_its_keys_bare_and_each_front_end_words_them():
    error = ReachError("line 5: cannot reach (check {setup.part_origin})", names_keys=("setup.part_origin",))
    assert str(error) == "line 5: cannot reach (check setup.part_origin)"          # a job file's key
    assert error.worded(_flag) == "line 5: cannot reach (check --part-origin)"     # the command line's flag


def test_only_the_keys_a_message_names_are_worded_not_a_users_text():
    error = InputError("use {units} inch, got '{units_x} {units}'", path="p{units}.stl", names_keys=("units",))
    assert error.worded(_flag) == "p{units}.stl: use --units inch, got '{units_x} --units'"
    plain = InputError("got '{units}'", path="a.stl")                              # names no key: as written
    assert plain.worded(_flag) == str(plain) == "a.stl: got '{units}'"


def test_a_wrapping_error_carries_the_keys_on():
    inner = ReachError("(check {setup.part_origin})", names_keys=("setup.part_origin",))
    outer = ReachError(f"{inner.carried()}; setup: ...", names_keys=inner.names_keys)
    assert outer.worded(_flag) == "(check --part-origin); setup: ..."
    restored = pickle.loads(pickle.dumps(outer))                                   # a --jobs worker's error
    assert restored.worded(_flag) == outer.worded(_flag) and str(restored) == str(outer)


def test_a_warning_names_its_keys_too():
    warning = Prs3Warning("is this STL in inches? use {units} inch", names_keys=("units",))
    assert (str(warning), warning.worded(_flag)) == ("is this STL in inches? use units inch",
                                                     "is this STL in inches? use --units inch")
