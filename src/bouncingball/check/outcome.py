"""What `bouncingball check` found: the hops merged into the contact, and the outcome with its verdict and report.

testing.check_result computes these; they only hold and word its numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..scenes import Scene


@dataclass(frozen=True)
class MergedHops:
    """The hops a result merged into the contact around them, each class counted.

    Attributes
    ----------
    by_solver : int
        Hops no higher than the FMU's hop resolution (cvode.merged_hop_limit for its rtol and atol).
    solver_limit : float
        That limit [m].
    by_tolerance : int
        Hops higher than that but no higher than the check's tolerance, which the file cannot show.
    tolerance : float
        The check's tolerance [m].
    """

    by_solver: int
    solver_limit: float
    by_tolerance: int
    tolerance: float

    @property
    def total(self) -> int:
        """All the hops merged."""
        return self.by_solver + self.by_tolerance

    def __str__(self) -> str:
        return (f"{self.total} hops merged into the contact: {self.by_solver} no higher than the FMU's hop "
                f"resolution {self.solver_limit:.3g} m, {self.by_tolerance} no higher than the tolerance "
                f"{self.tolerance:g} m")


@dataclass(frozen=True)
class CheckResult:
    """The outcome of a check: the worst height error, the impact count, and the verdict.

    Attributes
    ----------
    source : str
        The file checked (or "<columns>" for arrays passed directly).
    scene : Scene
        The scene with the start values (and the file's parameters) applied: the ball and the initial state.
    tolerance : float
        The allowed max |h - h_exact| [m] (beyond the file's printed resolution, if it has one).
    start_time : float
        When the run started from the scene's initial state [s].
    points : int
        Number of points compared.
    t_start, t_end : float
        First and last time in the result [s].
    max_height_error : float
        max |h - h_exact| [m].
    worst_time, worst_h, worst_h_exact : float
        Where that error is: the time [s], the result's height and the exact height [m].
    impacts_exact : int
        The exact number of impacts from start_time to t_end.
    impacts_found : int or None
        The last value of the result's impacts column; None when it has none.
    impact_mismatches : tuple of (time, found, exact)
        The points whose impact count is wrong (the exact count up to that time; empty if none).
    points_over : int
        Points whose |h - h_exact| exceeds the tolerance plus their printed resolution.
    over_time, over_error, over_allowance : float
        The point that exceeds its allowance most (or comes nearest to it): its time [s], its
        |h - h_exact| [m] and what it was allowed [m].
    printing : str
        How the file prints its numbers ("full precision", "6 significant digits", "6 decimals").
    max_resolution : float
        The most any point was allowed beyond the tolerance for the file's printing [m].
    instance : str
        The instance checked, as the file's columns name it ("" when they name none).
    parameters_from_file : str
        The parameter columns the file has, and which of them differ from the scene and were
        taken from it ("" when it has none).
    merged_hops : MergedHops or None
        The hops the impacts column merged into the contact (None without an impacts column).
    first_row : tuple of str
        How the first row (when it is the start) disagrees with the scene, each with the start value
        that would match the file.
    forcing : str
        Where a changing F_ext came from ("" when it was constant: the scene's F_ext).
    force_unrecorded : bool
        Neither the file (no F_ext column) nor an input file said what F_ext the master applied: a
        failed verdict then says how to give an input that drove it.
    conditioning : str
        Where the scene is ill-conditioned (a run of it by CVODE warns that its error estimate passes
        the promise), that warning; "" where it is not. The verdict does not depend on it.
    judge_error : float
        The exact solution's own error estimate [m] (ExactSolution.error_estimate): where it is above the
        tolerance, the judge cannot decide (but where a height is off by more than its allowance and the judge's
        error together), and the verdict says so instead of PASS or FAIL.
    """

    source: str
    scene: Scene
    tolerance: float
    start_time: float
    points: int
    t_start: float
    t_end: float
    max_height_error: float
    worst_time: float
    worst_h: float
    worst_h_exact: float
    impacts_exact: int
    impacts_found: int | None
    impact_mismatches: tuple[tuple[float, int, int], ...]
    points_over: int = 0
    over_time: float = math.nan
    over_error: float = math.nan
    over_allowance: float = math.nan
    printing: str = "full precision"
    max_resolution: float = 0.0
    instance: str = ""
    parameters_from_file: str = ""
    merged_hops: MergedHops | None = None
    first_row: tuple[str, ...] = ()
    forcing: str = ""
    force_unrecorded: bool = False
    conditioning: str = ""
    judge_error: float = 0.0

    @property
    def decided(self) -> bool:
        """False where the judge's own error estimate is above the tolerance: it cannot tell a pass from a fail.

        Unless a height is off by more than its allowance plus the judge's error: that fails whatever the judge's.
        """
        return self.judge_error <= self.tolerance or self.over_error - self.over_allowance > self.judge_error

    @property
    def heights_pass(self) -> bool:
        """True when every |h - h_exact| is within the tolerance (plus the point's printed resolution)."""
        return self.points_over == 0

    @property
    def passed(self) -> bool:
        """True when the heights are within the tolerance and the impacts column (if any) counts right.

        Only where the judge decided: its own error within the tolerance.
        """
        return self.decided and self.heights_pass and not self.impact_mismatches

    @property
    def _within(self) -> str:
        if not self.max_resolution:
            return f"the tolerance {self.tolerance:g} m"
        return f"the tolerance {self.tolerance:g} m plus the file's printed resolution ({self.printing})"

    @property
    def verdict(self) -> str:
        """PASS or FAIL, with the reason."""
        merged = f"; {self.merged_hops}" if self.merged_hops and self.merged_hops.total else ""
        if not self.decided:
            return (f"UNDECIDED: the judge's own error estimate, {self.judge_error:.3e} m (the exact solution's "
                    f"rounding, carried through an ill-conditioned run), is above the tolerance {self.tolerance:g} m: "
                    "it cannot tell a pass from a fail; loosen the tolerance above it or check a shorter run")
        if self.passed:
            return f"PASS: max |h - h_exact| = {self.max_height_error:.3e} m is within {self._within}" + \
                   ("" if self.impacts_found is None else f", impacts counted right{merged}")
        reasons = []
        if self.first_row:
            reasons.append("the first row is not the scene's start: " + "; ".join(self.first_row))
        if not self.heights_pass:
            if self.max_resolution:
                reasons.append(f"|h - h_exact| exceeds {self._within} at {self.points_over} of {self.points} "
                               f"points, most at t = {self.over_time!r} s ({self.over_error:.3e} m, allowed "
                               f"{self.over_allowance:.3e} m)")
            else:
                reasons.append(f"max |h - h_exact| = {self.max_height_error:.3e} m at t = {self.worst_time!r} s "
                               f"exceeds the tolerance {self.tolerance:g} m (at {self.points_over} of {self.points} "
                               "points)")
        if self.impact_mismatches:
            t, found, exact = self.impact_mismatches[0]
            reasons.append(f"the impacts column is wrong at {len(self.impact_mismatches)} points, first at "
                           f"t = {t!r} s ({found}, exact {exact}){merged}")
        if self.force_unrecorded:
            reasons.append("the file has no F_ext column: if an input drove F_ext, give its file with "
                           "--input-file F.csv (input_file in Python)")
        return "FAIL: " + "; ".join(reasons)

    def report(self) -> str:
        """The lines `bouncingball check` prints."""
        scene, ball = self.scene, self.scene.ball
        lines = [f"check {self.source} against the exact solution of scene {scene.name}"]
        if self.instance:
            lines.append(f"  instance           {self.instance}")
        lines += [f"  ball               m = {ball.m:g} kg, k = {ball.k:g} N/m, b = {ball.b:g} N s/m, "
                  f"R = {ball.R:g} m, g = {ball.g:g} m/s2, " +
                  (f"F_ext {self.forcing}" if self.forcing else f"F_ext = {scene.F_ext:g} N"),
                  f"  start              h = {scene.h0:.15g} m, v = {scene.v0:.15g} m/s at t = {self.start_time!r} s"]
        if self.parameters_from_file:
            lines.append(f"  file's parameters  {self.parameters_from_file}")
        lines.append(f"  points compared    {self.points} (t = {self.t_start!r} to {self.t_end!r} s)")
        if self.max_resolution:
            lines.append(f"  printed            {self.printing}: each point is allowed its printed resolution "
                         f"beyond the tolerance (that of h, plus |v| times that of time), at most "
                         f"{self.max_resolution:.3e} m")
        lines.append(f"  max |h - h_exact|  {self.max_height_error:.3e} m at t = {self.worst_time!r} s "
                     f"(h = {self.worst_h!r} m, exact {self.worst_h_exact!r} m)")
        merged = f"; {self.merged_hops}" if self.merged_hops and self.merged_hops.total else ""
        if self.impacts_found is None:
            lines.append(f"  impacts            no impacts column (exact: {self.impacts_exact})")
        elif not self.impact_mismatches:
            lines.append(f"  impacts            {self.impacts_found} at the end, exact {self.impacts_exact}; "
                         f"the count is right at every point{merged}")
        else:
            lines.append(f"  impacts            {self.impacts_found} at the end, exact {self.impacts_exact}; "
                         f"the count is wrong at {len(self.impact_mismatches)} points{merged}:")
            lines += [f"    t = {t!r} s: {found}, exact {exact}" for t, found, exact in self.impact_mismatches[:5]]
        if self.conditioning:
            lines.append(f"  ill-conditioned    {self.conditioning}: no master can be trusted there either")
        lines.append(f"  judge's error      {self.judge_error:.3e} m (the exact solution's own estimate)")
        lines.append(f"  verdict            {self.verdict}")
        return "\n".join(lines)
