"""`bouncingball check`: a co-simulation master's result judged against the exact solution.

judge.py judges (check_result); result_files.py and printed_numbers.py read a master's result file as it was
written, input_files.py the F_ext it applied; outcome.py words the verdict.
"""
