"""The admission rule, measured on whole train cells: the spec ranks exactly the classes the rule
admits (``scftc admission --benchmark scftc-v4`` prints the same table)."""

from __future__ import annotations

from scftc_cli.study.admission import admission_table, markdown, rule_of
from scftc_cli.versions.v4.spec import V4


def test_the_spec_ranks_exactly_the_classes_the_rule_admits_on_train():
    rule = rule_of(V4)
    rows = admission_table(V4.version)
    table = markdown(rows, rule, rule.split)
    assert [row.fault_class for row in rows] == list(V4.fault_classes)
    whole = [V4.n_faults] * 2
    assert all([len(row.oracle.by_fault), len(row.unaware.by_fault)] == whole for row in rows), table
    wrong = [row.fault_class for row in rows if not row.consistent]
    assert not wrong, f"ranked classes disagree with the rule on {wrong}:\n{table}"
    assert "nominal" not in V4.ranked_classes
    # the rule is not vacuous: every ranked class is flown by the oracle and lost by pid
    for row in rows:
        if row.ranked:
            assert row.oracle.rate >= rule.oracle_at_least and row.unaware.rate <= rule.unaware_at_most, table


def test_the_rule_refuses_what_it_should():
    rule = rule_of(V4)
    assert rule.admits(0.95, 0.50) and not rule.admits(0.949, 0.1) and not rule.admits(1.0, 0.501)
