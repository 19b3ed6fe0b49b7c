"""The two CVODE engines the phase machine runs on.

scikit-sundae's, which runs the machine interpreted (stepper.py, with sksundae_events.py), and the compiled one:
numba over the SUNDIALS library scikit-sundae installs (compiled.py, jit.py, sundials.py), compiled ahead at a
build (ahead_of_time.py); sundials_log.py keeps SUNDIALS' own text off the terminal for both.
"""
