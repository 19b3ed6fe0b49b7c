"""The BouncingBall FMI 2.0 co-simulation FMU: its variables, build, validation, slave and loader.

``variables`` is the interface (read by the build and by the slave); ``slave`` is the slave;
``build`` packs the script that names it, ``bouncingball_fmu_slave.py``, and the C loader
``bouncingball_fmu_loader.c`` with pythonfmu; ``validate`` runs the FMU through FMPy against the exact solution.
"""
