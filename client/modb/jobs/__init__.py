"""Long work as jobs (issue 42): graph builds and the like queued in the database with Procrastinate
(its tables beside modb's; workers on any machine that reaches the database), computed in the worker
process with the kernel, their progress, log and result readable by SQL in the view modb.jobs."""
