"""The kernel warm-up (python -m raylume.warmup): its parts cover every job once; `raylume
warmup` says what it does as it does it."""

import subprocess
import sys
import time

import pytest

from raylume.warmup import JOBS, main, part_of, warm_in_processes


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


def test_warm_in_processes_reports_each_line_as_it_comes(monkeypatch):
    """A line at the start, each part's lines as that process prints them (not when it ends), and
    the total; here each part is a stand-in that prints a line, waits, and prints another."""
    real_popen = subprocess.Popen
    child = "import sys, time; print(sys.argv[1], 'first'); time.sleep(1.0); print(sys.argv[1], 'last')"

    def stand_in(args, **kwargs):
        return real_popen([sys.executable, "-u", "-c", child, args[-1]], **kwargs)

    monkeypatch.setattr(subprocess, "Popen", stand_in)
    lines: list[tuple[float, str]] = []
    assert warm_in_processes(2, lambda line: lines.append((time.perf_counter(), line)))
    texts = [text for _, text in lines]
    assert texts[0].startswith("compiling every kernel in 2 processes side by side"), texts
    assert texts[-1].startswith("every kernel compiled (or loaded from the cache) in "), texts
    assert sorted(texts[1:-1]) == ["0/2 first", "0/2 last", "1/2 first", "1/2 last"], texts
    when = {text: t for t, text in lines}
    assert when["0/2 first"] < when["0/2 last"] - 0.5  # reported while the part still ran


def test_a_part_says_it_is_done_without_repeating_warm_up(monkeypatch, capsys):
    monkeypatch.setattr("raylume.warmup.JOBS", [])
    main(["--part", "1/2"])
    assert capsys.readouterr().out.startswith("part 2 of 2 done in "), "a part's last line names the part once"
