"""Partial credit that follows an exercise's parts, and hints across exercises (pytest_plugin).

Unit tests of :func:`robolab.grading.running.credit.settle` on report records;
the mutation suite (``tests/labs/mutants``) checks the same through real grading.
"""

from __future__ import annotations

from robolab.grading.running.credit import settle
from robolab.grading.running.pytest_plugin import failure_message


def _rec(test, outcome, exercise="f", requires=(), uses=(), message=""):
    return {
        "nodeid": f"tests/labs/test_x.py::{test}",
        "module": "tests/labs/test_x.py",
        "test": test.split("[")[0],
        "description": f"{exercise}: {test}",
        "exercise": exercise,
        "points": 5.0,
        "outcome": outcome,
        "message": message,
        "requires": list(requires),
        "uses": list(uses),
    }


def _by_test(records):
    return {r["nodeid"].split("::")[1]: r for r in records}


def test_a_refusal_pays_only_with_its_valid_input_tests():
    """A passed refusal test whose required value test failed becomes failed, naming it."""
    raw = [_rec("test_values", "failed"), _rec("test_refuses", "passed", requires=["test_values"])]
    out = _by_test(settle(raw))
    assert out["test_refuses"]["outcome"] == "failed", f"gated test should fail, got {out}"
    assert "f: test_values" in out["test_refuses"]["message"], (
        f"the message must name the test it waits for, got {out['test_refuses']['message']!r}"
    )
    assert raw[1]["outcome"] == "passed", "settle must not modify the collector's records"


def test_every_parametrization_of_a_required_test_counts_and_gates_chain():
    """One failing parametrization gates; a gate on a gated test fails too."""
    raw = [
        _rec("test_values[a]", "passed"),
        _rec("test_values[b]", "failed"),
        _rec("test_e2e", "passed", requires=["test_values"]),
        _rec("test_refuses", "passed", requires=["test_e2e"]),
    ]
    out = _by_test(settle(raw))
    assert out["test_e2e"]["outcome"] == "failed", "test_values[b] failed: the gate must hold"
    assert out["test_refuses"]["outcome"] == "failed", "a gate on a gated test must hold too"
    ok = _by_test(settle([_rec("test_values[a]", "passed"), raw[2]]))
    assert ok["test_e2e"]["outcome"] == "passed", "all required tests passed: the test pays"


def test_a_failure_points_to_the_wrong_function_it_uses():
    """When p_max fails its own checks, a failing model test notes that p_max is wrong too."""
    raw = [
        _rec("test_p_max", "failed", exercise="p_max"),
        _rec("test_p_hit", "passed", exercise="p_hit"),
        _rec("test_model", "failed", exercise="model", uses=["p_max", "p_hit"], message="off"),
    ]
    message = _by_test(settle(raw))["test_model"]["message"]
    assert message.startswith("off") and "`p_max` is wrong" in message, (
        f"expected the original message and a hint naming p_max, got {message!r}"
    )
    assert "p_hit" not in message, f"p_hit passes its checks and must not be blamed: {message!r}"
    clean = _by_test(settle(raw[1:]))["test_model"]["message"]
    assert clean == "off", f"no used function fails: no hint expected, got {clean!r}"


def test_did_not_raise_is_said_in_words():
    """pytest.raises' 'DID NOT RAISE' becomes a sentence about refusing bad input."""
    text = failure_message(None, "Failed: DID NOT RAISE <class 'ValueError'>")
    assert "expected ValueError" in text and "refuse" in text, f"got {text!r}"
