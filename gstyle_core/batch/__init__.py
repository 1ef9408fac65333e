"""``gstyle batch``'s machinery: the plan of runs (``plan``), the jobs (``jobs``), the local pool (``pool``), Ray
tasks (``ray_tasks``) and the report (``report``). It drives ``gstyle stylize`` jobs it is handed by the command line
(``gstyle_core/cli/batch.py``) and never imports the command line."""
