"""A fleet of robots: the fleet file → one job per robot, run on a task engine, → the fleet table.

Where things happen: the client reads each robot's files (data, description, previous model)
and sends their bytes to the cluster; a task puts them in a scratch folder of its own worker,
works there (the training and the report are library calls) and sends back the files it made
(the model, its card, the held-out rows, the report), which the client writes into ``-o`` (each
robot's folder whole or not at all). So a real cluster — ``dask scheduler`` and ``dask worker``
processes started elsewhere, with other working directories or other disks — reads and writes
exactly what the local one does, and messages name the client's paths.

Modules: ``jobs`` (the fleet file → RobotJobs, their training settings, their inputs), ``tasks``
(a robot's training and report, its outputs), ``cluster`` (Dask: the local cluster, run_fleet,
task_map for a search's candidates), ``table`` (the fleet table).
"""
