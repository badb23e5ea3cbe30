"""simgap.fleet: every robot of a fleet diagnosed every day on a Dask cluster, and the effects
tracked as they drift.

Needs the optional dependencies: ``pip install "./python[fleet]"`` (``dask[distributed]``,
``pandas``, ``pyarrow``).

Example::

    from simgap import fleet

    index = fleet.index_from_folder("logs/")          # logs/ROBOT/DAY/*.mcap
    result = fleet.diagnose_fleet(index, "arm.urdf")  # a LocalCluster; or client=Client("tcp://…")
    result.table                                      # one row per robot, day, effect, joint, parameter
    result.drift()[lambda d: d.drifting]              # whose parameters trend over the days
    result.outliers()[lambda d: d.outlier]            # who stands out from the fleet, which day
    result.to_parquet("fleet.parquet"); result.to_html("fleet.html")
"""

from .index import HOLDOUT_RULE, Task, index_from_folder, index_from_table, tasks_from_index
from .report import flagged_robots, summary_text, write_html
from .run import TABLE_COLUMNS, FleetResult, diagnose_fleet, diagnose_task, iter_fleet, report_rows
from .trends import day_numbers, drift, outliers, series_table

__all__ = [
    "HOLDOUT_RULE",
    "TABLE_COLUMNS",
    "FleetResult",
    "Task",
    "day_numbers",
    "diagnose_fleet",
    "diagnose_task",
    "drift",
    "flagged_robots",
    "index_from_folder",
    "index_from_table",
    "iter_fleet",
    "outliers",
    "report_rows",
    "series_table",
    "summary_text",
    "tasks_from_index",
    "write_html",
]
