"""The phase machine: CVODE phase by phase, written once for both engines.

Its decisions (phases.py), its one phase routine and event (machine.py) and drivers (drivers.py), its state
(layout.py), its error estimate (error_estimate.py) and dense output (dense_output.py), CVODE's settings and the
tolerance's rules (settings.py), and the protocol it calls its engine by (engine_protocol.py).
"""
