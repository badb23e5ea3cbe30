"""simgap.fleet: every robot of a fleet diagnosed every day on a Dask cluster, and the effects
tracked as they change.

Needs the optional dependencies: ``pip install "./python[fleet]"`` (``dask[distributed]``,
``pandas``, ``pyarrow``, ``matplotlib``).

Example::

    from simgap import fleet

    index = fleet.index_from_folder("logs/")          # logs/ROBOT/DAY/*.mcap
    result = fleet.diagnose_fleet(index, "arm.urdf")  # a LocalCluster; or client=Client("tcp://…")
    result.table                                      # one row per robot, day, effect, joint, parameter
    result.findings()                                 # drifts, steps, effects the fleet lacks, outliers
    result.to_parquet("fleet.parquet"); result.to_html("fleet.html")
"""

from .findings import FLAG_COLUMNS, Findings, find, flagged_robots
from .index import HOLDOUT_RULE, Task, index_from_folder, index_from_table, tasks_from_index
from .report import summary_text, write_html
from .result import TABLE_COLUMNS, FleetResult, report_rows
from .run import diagnose_fleet, diagnose_task, iter_fleet
from .trends import day_numbers, drift, outliers, series_table
from .vocabulary import is_parameter, min_change, neutral, unit

__all__ = [
    "FLAG_COLUMNS",
    "HOLDOUT_RULE",
    "TABLE_COLUMNS",
    "Findings",
    "FleetResult",
    "Task",
    "day_numbers",
    "diagnose_fleet",
    "diagnose_task",
    "drift",
    "find",
    "flagged_robots",
    "index_from_folder",
    "index_from_table",
    "is_parameter",
    "iter_fleet",
    "min_change",
    "neutral",
    "outliers",
    "report_rows",
    "series_table",
    "summary_text",
    "tasks_from_index",
    "unit",
    "write_html",
]
