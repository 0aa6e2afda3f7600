"""train --search's candidates as Dask tasks: on a given scheduler, and from inside a task (a
fleet's robot) on that task's own cluster; the same scores and choice as in one process."""
import pytest

pytest.importorskip("dask.distributed")
pytest.importorskip("torch")


SEARCH = dict(structures=[(3,), (4,), (3, 3)], keep=2, final_seeds=1, epochs=10, screen_epochs=20, method="plain")


def _search_in_a_task(poses, errors):
    """What a fleet's robot does with train --search: the search from inside a task."""
    from postproc.fleet.tasks import task_map
    from postproc.model.training.search import search_structure

    with task_map() as map_fn:
        assert map_fn is not None
        return search_structure(poses, errors, map_fn=map_fn, **SEARCH)


def test_structure_search_runs_its_candidates_as_tasks_on_the_cluster():
    from dask.distributed import Client, LocalCluster, get_task_stream

    from postproc.fleet.tasks import task_map
    from postproc.model.training.search import search_structure
    from postproc.model.training.synthetic import synthetic_measurements

    poses, measured = synthetic_measurements(120, seed=3)
    errors = poses[:, :3] - measured
    with task_map() as map_fn:
        assert map_fn is None  # no scheduler, not in a worker: the fits run here
    here = search_structure(poses, errors, **SEARCH)
    scores = lambda r: [(c.hidden, c.screen_mm, c.final_mm) for c in r.candidates]  # noqa: E731
    # one worker of one thread: the task that searches must give its thread to its candidates
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as cluster, \
            Client(cluster) as client:
        with get_task_stream(client) as stream:
            with task_map(cluster.scheduler_address) as map_fn:
                given = search_structure(poses, errors, map_fn=map_fn, **SEARCH)
            inside = client.submit(_search_in_a_task, poses, errors, pure=False).result()
    fits = [t for t in stream.data if str(t["key"]).startswith("fit_and_score")]
    assert len(fits) == 2 * (3 + 2)  # per search: 3 screened candidates, 2 finalists × 1 seed
    # seeded fits: where they ran does not change the search's scores or its choice
    assert scores(given) == scores(inside) == scores(here)
    assert given.best == inside.best == here.best
    assert len({c.screen_mm for c in here.candidates}) == 3
