"""The kernel warm-up (python -m raylume.warmup): its parts cover every job once."""

import pytest

from raylume.warmup import JOBS, main, part_of


@pytest.mark.parametrize("parts", [1, 2, 3, 5])
def test_parts_cover_every_job_once(parts):
    jobs = [job for part in range(parts) for job in part_of(JOBS, part, parts)]
    assert sorted(job.__name__ for job in jobs) == sorted(job.__name__ for job, _ in JOBS)


def test_two_parts_are_about_even():
    costs = dict((job.__name__, cost) for job, cost in JOBS)
    loads = [sum(costs[job.__name__] for job in part_of(JOBS, part, 2)) for part in range(2)]
    assert max(loads) <= 0.6 * sum(loads)


def test_a_part_out_of_range_is_refused(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--part", "2/2"])
    assert exc.value.code == 2
    assert "--part 2/2" in capsys.readouterr().err
