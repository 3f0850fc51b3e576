"""Statistical checks and reports of rig experiments (work on recordings or on in-memory data)."""
from rig.analysis.capability import capability, describe
from rig.analysis.lag import compare_theory, estimate_lag
from rig.analysis.normality import normality
from rig.analysis.sets import curve_verdicts, event_counts, set_statistics, statistics_by_program
from rig.analysis.summary import analyse
from rig.analysis.trend import runs_test, trend

__all__ = ["capability", "describe", "compare_theory", "estimate_lag", "normality", "curve_verdicts",
           "event_counts", "set_statistics", "statistics_by_program", "analyse", "runs_test", "trend"]
