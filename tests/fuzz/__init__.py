"""Fuzz suite for rotavat's hostile-input promises (issue 15).

``corpus`` generates a fixed, seeded corpus of hostile inputs (one generator per input class),
``harness`` runs one case and checks the rules, ``test_fuzz_corpus`` runs the corpus under pytest
(``-m fuzz``) and ``run_fuzz.py`` is the longer randomized campaign (``make fuzz``).
"""
