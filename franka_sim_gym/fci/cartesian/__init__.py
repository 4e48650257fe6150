"""The Cartesian motion generators (O_T_EE_c, O_dP_EE_c): judged by their precedence
tables (fci/limits/cartesian*.py), extrapolated, differenced, solved to joint space and
driven: generators.py (the generators, the cycle), step.py (one cycle's candidates and
the IK), checks.py, record.py and reference.py (their history).
"""
