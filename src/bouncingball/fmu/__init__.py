"""The BouncingBall FMU (FMI 2.0 co-simulation; FMI 3.0 co-simulation and model exchange): its variables, build,
validation, slave and loaders.

``variables`` is the interface (read by the build and by the slave); ``slave_base`` is the slave, ``slave``
(pythonfmu) and ``slave3`` (pythonfmu3) its classes; ``build`` (and ``build3`` for FMI 3.0) packs the script that
names it, ``bouncingball_fmu_slave.py``, and the C loader ``bouncingball_fmu_loader.c`` (or
``bouncingball_fmu3_loader.c``) with pythonfmu or pythonfmu3; ``validate`` runs the FMU through FMPy against the
exact solution.
"""
