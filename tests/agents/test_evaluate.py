"""The evaluation's tables: what each policy calls at test time, the summary's rows and
cells, the results page and the command's options (no episode of a real policy runs here)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

from agents import config as cf
from agents import episodes as ep
from agents import evaluate as ev
from agents import models, provenance
from agents import summary as sm
from agents import sweep_page as sp
from agents.planner_agents import PlannerGrip, PlannerHandover, PlannerResidual
from agents.planner_base import PlannerAgent

REPO = Path(__file__).resolve().parents[2]

#: What every config file's models call at test time, by file (each file's every entry).
CONFIG_TEST_TIMES = {
    "ppo.yml": "network",
    "ppo_batched.yml": "network",
    "ppo_uncertainty.yml": "network",
    "ppo_finetune.yml": "network",
    "ppo_planner_starts.yml": "network",
    "ppo_scene_starts.yml": "network",
    "ppo_scene_starts_no_shaping.yml": "network",
    "ppo_scene_starts_no_curriculum.yml": "network",
    "ppo_lift_starts.yml": "network",
    "ppo_lift_starts_half.yml": "network",
    "ppo_lift_leave.yml": "network",
    "ppo_residual.yml": "planner",
    "ppo_handover.yml": "planner",
    "ppo_grip.yml": "simulator",
}
#: What every shipped model calls at test time.
SHIPPED_TEST_TIMES = {
    "fig13_fingers": "network",
    "fig13_perturbed": "network",
    "random_shapes_palm": "network",
    "lift_palm": "network",
    "lift_residual": "planner",
    "lift_grip": "simulator",
    "scene_starts": "network",
}


def test_every_config_file_is_classified():
    assert sorted(CONFIG_TEST_TIMES) == sorted(p.name for p in (REPO / "configs").glob("ppo*.yml"))
    assert sorted(SHIPPED_TEST_TIMES) == sorted(p.name for p in models.MODEL_DIR.iterdir())


@pytest.mark.parametrize("name", sorted(CONFIG_TEST_TIMES))
def test_config_entries_declare_what_they_call_at_test_time(name):
    for env_id in cf.load_config(REPO / "configs" / name):
        entry = cf.get_entry(cf.load_config(REPO / "configs" / name), env_id)
        assert models.entry_test_time(entry) == CONFIG_TEST_TIMES[name], (name, env_id)


def test_shipped_models_by_their_config_file_and_env_id():
    """The shipped models' table: each model calls what its config file's entry declares."""
    for (conf_file, _), name in models.SHIPPED.items():
        assert SHIPPED_TEST_TIMES[name] == CONFIG_TEST_TIMES[Path(conf_file).name], name


@pytest.mark.parametrize("name", sorted(SHIPPED_TEST_TIMES))
def test_shipped_models_specs_carry_their_test_time(name):
    assert ep.ppo_spec(models.MODEL_DIR / name).test_time == SHIPPED_TEST_TIMES[name]


def test_test_time_is_declared_by_the_agent_kind():
    """Planner agents declare ``planner``; the grip agent's turn probes (``simulate_action``
    on a copy) make it ``simulator``; the other kinds by the evaluation's table."""
    for cls in (PlannerResidual, PlannerHandover, PlannerGrip):
        assert issubclass(cls, PlannerAgent) and cls.test_time_of({}) == "planner"
    assert PlannerGrip.test_time_of({"probe_turns": True}) == "simulator"
    assert PlannerGrip.test_time_of({"probe_turns": False, "palm_only": True}) == "planner"
    assert PlannerResidual.test_time_of({"probe_turns": True}) == "planner"  # no such option
    assert ep.PolicySpec("scripted", "scripted").test_time == "planner"
    assert ep.PolicySpec("scripted_in_place", "scripted_in_place").test_time == "planner"
    assert ep.PolicySpec("random", "random").test_time == "network"
    assert ep.PolicySpec("x", "rllib").test_time == "network"
    assert ep.PolicySpec("x", "ppo").test_time == "network"  # no wrapper: its network alone
    assert ep.PolicySpec("x", "ppo", wrapper=(PlannerHandover, {})).test_time == "planner"
    with pytest.raises(ValueError, match="needs test_time"):
        ep.PolicySpec("x", "oracle")
    with pytest.raises(ValueError, match="test_time must be one of"):
        ep.PolicySpec("x", "random", test_time="oracle")
    entry = {"env_wrapper": [{"agents.planner_agents.PlannerGrip": {"probe_turns": True}}]}
    assert models.entry_test_time(entry) == "simulator"
    assert models.entry_test_time({"env_wrapper": "agents.wrappers.TrainingInfo"}) == "network"


def _episode(suite, scene, policy, seed, success=False, grip_W=math.nan, steps=math.nan):
    return ep.Episode(
        suite,
        scene,
        policy,
        seed,
        steps=20,
        success=success,
        reached=success,
        steps_to_closure=steps,
        grip=grip_W,
        grip_W=grip_W,
    )


EPISODES = [
    _episode("bundled", "fig13", "scripted", 0, True, 1.5, 27),
    _episode("bundled", "fig13", "random", 0),
    _episode("lift", "shape_1000000", "scripted", 1_000_000, True, 2.0, 30),
    _episode("lift", "shape_1000001", "scripted", 1_000_001),
    _episode("lift", "shape_1000000", "random", 1_000_000),
    _episode("lift", "shape_1000001", "random", 1_000_001),
]
TEST_TIMES = {"scripted": "planner", "random": "network"}


def test_rows_say_what_each_policy_calls_and_fig13_alone_has_no_bundled_rows():
    rows = sm.summarize(EPISODES, TEST_TIMES)
    assert [(r["suite"], r["policy"], r["test_time"]) for r in rows] == [
        ("fig13", "scripted", "planner"),
        ("fig13", "random", "network"),
        ("lift", "scripted", "planner"),
        ("lift", "random", "network"),
    ]
    more = [*EPISODES, _episode("bundled", "square", "random", 0)]
    suites = [r["suite"] for r in sm.summarize(more, TEST_TIMES)]
    assert suites.count("bundled") == 2 and suites.count("fig13") == 2


def test_empty_cells_read_n_a():
    table = sm.markdown_table(sm.summarize(EPISODES, TEST_TIMES))
    lines = table.splitlines()
    assert lines[0].startswith("| suite | policy | test time | n | success (95% CI) |")
    assert "| fig13 | scripted | planner | 1 | 1.00 (0.21-1.00) | 1.50 ± 0.00" in table
    assert "| lift | random | network | 2 | 0.00 (0.00-0.66) | n/a | n/a | 0 | 0 | 0 |" in table
    assert "- ± -" not in table and "(---)" not in table and "nan" not in table


def test_summary_files_have_the_test_time_column(tmp_path, monkeypatch):
    pytest.importorskip("matplotlib", reason="the viz extra draws the chart")
    rows = sm.summarize(EPISODES, TEST_TIMES)
    sm.write_csv(tmp_path / "summary.csv", rows)
    with open(tmp_path / "summary.csv") as f:
        read = list(csv.DictReader(f))
    assert [r["test_time"] for r in read] == ["planner", "network", "planner", "network"]
    sm.bar_chart(tmp_path / "summary.png", rows)
    assert (tmp_path / "summary.png").stat().st_size > 0


def test_results_page_names_date_commit_command_and_network_rows():
    rows = sm.summarize(EPISODES, TEST_TIMES)
    command = "python -m agents.evaluate --scenes fig13 --lift-episodes 2"
    page = sm.results_page(rows, command, "2026-01-02 03:04 UTC", "abc1234")
    assert page.startswith("# Results\n")
    assert "Generated on 2026-01-02 03:04 UTC at commit `abc1234` by:" in page
    assert f"```bash\n{command}\n```" in page
    assert "Network-only rows: `random`." in page
    assert "Rows of `planner` policies: `scripted`." in page
    assert "## `fig13`: " in page and "## `lift`: " in page and "## `bundled`" not in page
    assert "| lift | random | network | 2 |" in page
    assert provenance.git_commit(REPO) != "unknown"


def test_policies_are_paired_with_the_planner_shape_by_shape():
    ok = [(0, 1.0, 1.5), (1, 2.0, 2.0), (2, 1.0, None), (3, math.inf, 4.0), (4, None, 1.0),
          (5, None, None)]  # fmt: skip
    episodes = []
    for k, planner, policy in ok:
        for name, grip in (("scripted", planner), ("ppo_x", policy)):
            args = (True, grip, 10) if grip is not None else ()
            episodes.append(_episode("heldout", f"shape_{k}", name, k, *args))
    episodes.append(_episode("bundled", "fig13", "ppo_x", 0, True, 1.0, 5))  # not paired
    (row,) = sm.paired_rows(episodes, {"ppo_x": "network"})
    assert (row["suite"], row["policy"], row["test_time"]) == ("heldout", "ppo_x", "network")
    assert row["episodes"] == 6
    assert (row["policy_only"], row["reference_only"]) == (1, 1)  # shapes 4 and 2
    # both grasp with finite y* on shapes 0 and 1 (shape 3's planner grip is infinite)
    assert row["both"] == 2 and row["grip_W_diff_mean"] == pytest.approx(0.25)
    assert 0.0 <= row["grip_W_diff_ci_low"] <= 0.25 <= row["grip_W_diff_ci_high"] <= 0.5
    assert (row["lower"], row["equal"], row["higher"]) == (0, 1, 1)
    page = sm.results_page(sm.summarize(episodes), "cmd", "date", "abc")
    assert "shape by shape" not in page  # only where asked
    page = sm.results_page(sm.summarize(episodes), "cmd", "date", "abc", paired=[row])
    heldout = page[page.index("## `heldout`") :]
    assert "| heldout | ppo_x | network | 6 | 1 | 1 | 2 | +0.25 (" in heldout
    assert "| 0 / 1 / 1 |" in heldout
    assert sm.paired_rows(episodes, reference="nobody") == []


def test_policies_are_paired_with_the_planner_in_place_too():
    """Where ``scripted_in_place`` played, every policy (the planner too) is also compared
    with it, in a table of its own under the planner's."""
    grasps = {"scripted": (1, 1, 1, 0), "scripted_in_place": (1, 0, 0, 0), "ppo_x": (1, 1, 0, 1)}
    episodes = [
        _episode("lift", f"shape_{k}", name, k, *((True, 1.0, 10) if ok else ()))
        for name, oks in grasps.items()
        for k, ok in enumerate(oks)
    ]
    times = {"scripted": "planner", "scripted_in_place": "planner", "ppo_x": "network"}
    paired = [r for ref in sm.REFERENCE_NAMES for r in sm.paired_rows(episodes, times, ref)]
    counts = {
        (r["reference"], r["policy"]): (r["policy_only"], r["reference_only"]) for r in paired
    }
    assert counts == {
        ("scripted", "scripted_in_place"): (0, 2),
        ("scripted", "ppo_x"): (1, 1),
        ("scripted_in_place", "scripted"): (2, 0),  # the shapes that need another placement
        ("scripted_in_place", "ppo_x"): (2, 0),
    }
    page = sm.results_page(sm.summarize(episodes), "cmd", "date", "abc", paired=paired)
    planner = page.index("Against the planner (`scripted`)")
    in_place = page.index("Against the planner in place (`scripted_in_place`)")
    assert planner < in_place
    assert "| by the planner in place alone |" in page[in_place:]
    assert "| lift | scripted | planner | 4 | 2 | 0 | 1 |" in page[in_place:]


def test_results_page_links_the_metrics_from_where_it_is_written(tmp_path, monkeypatch):
    rows = sm.summarize(EPISODES, TEST_TIMES)
    monkeypatch.setattr(ev, "evaluate", lambda *a, **k: (rows, []))
    monkeypatch.setattr(ev, "default_policies", lambda *a: [])
    monkeypatch.setattr(ev, "DOCS", tmp_path / "docs")
    for page, link in [("docs/results.md", "training.md"), ("docs/a/b.md", "../training.md")]:
        (tmp_path / page).parent.mkdir(parents=True, exist_ok=True)
        ev.main(["--models", "--out", str(tmp_path / "eval"), "--results-page",
                 str(tmp_path / page)])  # fmt: skip
        assert f"[training.md]({link}#evaluation)" in (tmp_path / page).read_text()


def test_results_page_is_written_only_where_asked(tmp_path, monkeypatch, capsys):
    rows = sm.summarize(EPISODES, TEST_TIMES)
    monkeypatch.setattr(ev, "evaluate", lambda *a, **k: (rows, []))
    monkeypatch.setattr(ev, "default_policies", lambda *a: [])
    shipped = REPO / "docs" / "results.md"
    before = shipped.read_bytes() if shipped.exists() else None
    ev.main(["--models", "--out", str(tmp_path / "eval")])
    assert (shipped.read_bytes() if shipped.exists() else None) == before
    assert not list(tmp_path.rglob("*.md"))
    page = tmp_path / "results.md"
    ev.main(["--models", "--out", str(tmp_path / "eval"), "--results-page", str(page)])
    text = page.read_text()
    assert "python -m agents.evaluate --models --out " in text and "--results-page" in text
    for bad, message in ((tmp_path, "is a directory"), (tmp_path / "no" / "r.md", "folder")):
        with pytest.raises(SystemExit):
            ev.main(["--models", "--out", str(tmp_path / "eval"), "--results-page", str(bad)])
        assert message in capsys.readouterr().err


def test_readme_block_is_written_from_the_page(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # a refused call makes no default --out folder here
    rows, paired = sm.summarize(EPISODES, TEST_TIMES), sm.paired_rows(EPISODES, TEST_TIMES)
    monkeypatch.setattr(ev, "evaluate", lambda *a, **k: (rows, paired))
    monkeypatch.setattr(ev, "default_policies", lambda *a: [])
    readme = tmp_path / "README.md"
    readme.write_text(f"# Title\n\nbefore\n\n{sm.README_BEGIN}\nold\n{sm.README_END}\n\nafter\n")
    page = tmp_path / "docs" / "results.md"
    page.parent.mkdir()
    argv = ["--models", "--out", str(tmp_path / "eval"), "--results-page", str(page)]
    ev.main([*argv, "--readme", str(readme)])
    text = readme.read_text()
    assert text.startswith("# Title\n\nbefore\n\n") and text.endswith("\n\nafter\n")
    assert "old" not in text
    block = text[text.index(sm.README_BEGIN) : text.index(sm.README_END)]
    assert "From [results.md](docs/results.md), generated on " in block
    assert "Network-only rows: `random`." in block
    # the lift suite's table under its header, as on the page; its comparison with the
    # planner, shape by shape, only on the page
    table = sm.markdown_table([r for r in rows if r["suite"] == "lift"])
    assert table in page.read_text() and table in block
    assert block.count(sm.TABLE_HEAD.splitlines()[0]) == 1
    assert "| lift | random | network | 2 | 0 | 1 | 0 | n/a | 0 / 0 / 0 |" in page.read_text()
    assert "grasped by it alone" not in block
    assert "| fig13 |" not in block  # the README shows the seeded suites only
    for bad, message in (
        ([*argv, "--readme", str(tmp_path / "none.md")], "is not a file"),
        ([*argv, "--readme", str(page)], "has no results block"),
        (["--models", "--readme", str(readme)], "needs --results-page"),
    ):
        with pytest.raises(SystemExit):
            ev.main(bad)
        assert message in capsys.readouterr().err


def test_shipped_readme_shows_the_shipped_results_page():
    """The README's results block is what ``--readme`` writes from ``docs/results.md``."""
    text = (REPO / "README.md").read_text()
    block = text[text.index(sm.README_BEGIN) : text.index(sm.README_END) + len(sm.README_END)]
    page = (REPO / "docs" / "results.md").read_text()
    assert block == sm.readme_results(page, "docs/results.md")


def test_help_shows_every_default(capsys):
    with pytest.raises(SystemExit):
        ev.main(["--help"])
    out = " ".join(capsys.readouterr().out.split())
    for option, default in (
        ("--episodes N held-out shapes", "(default: 20)"),
        ("suite 'wide'", "(default: 0)"),
        ("suite 'lift'", "(default: 0)"),
        ("suite 'perturbed'", "(default: 0)"),
        ("seeds per scene", "(default: 1)"),
        ("output directory", "(default: runs/evaluation)"),
    ):
        assert f"{option} {default}" in out, option
    assert "(default: the env's time limit, 200)" in out and "default: none" in out
    assert "(default: None)" not in out and "(default: [])" not in out


#: option: its parser, a text and its levels, bad texts, one good level (too few for a page)
LEVELS = {
    "friction": (ev.friction_levels, "0.3,0,0.1", (0.0, 0.1, 0.3),
                 ("0.1,x", "-0.1", "nan", "0.1,0.1", "2e6"), "0.2"),
    "uncertainty": (ev.uncertainty_levels, "0.02,0,0.005", (0.0, 0.005, 0.02),
                    ("0.1,x", "-0.01", "nan", "0.01,0.01", "2"), "0.01"),
}  # fmt: skip


@pytest.mark.parametrize("option", LEVELS)
def test_levels_are_parsed_and_refused_by_name(option, capsys):
    parse, text, parsed, bads, one = LEVELS[option]
    assert parse(text) == parsed
    for bad in bads:
        with pytest.raises(SystemExit):
            ev.main(["--models", f"--{option}", bad])
        assert f"--{option}" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        ev.main(["--models", f"--{option}", one, f"--{option}-page", "x.md"])
    assert f"--{option}-page needs two or more" in capsys.readouterr().err


def test_rows_at_each_friction_and_the_friction_page(tmp_path):
    """Episodes at two coefficients: a row per coefficient, the zero rows as without
    friction, and a page whose table has one success column per coefficient."""
    rough = [ep.Episode(**{**e.__dict__, "friction": 0.3}) for e in EPISODES]
    rough[0].success = False
    rows = sm.summarize(EPISODES + rough, TEST_TIMES)
    plain = sm.summarize(EPISODES, TEST_TIMES)
    assert rows[: len(plain)] == plain
    assert [r["friction"] for r in rows] == [0.0] * len(plain) + [0.3] * len(plain)
    assert "| fig13 (mu 0.3) | scripted | planner | 1 | 0.00" in sm.markdown_table(rows)
    table = sp.sweep_table(rows, sp.FRICTION)
    assert table.splitlines()[0] == "| suite | policy | test time | n | mu = 0 | mu = 0.3 |"
    assert "| fig13 | scripted | planner | 1 | 1.00 (0.21-1.00) | 0.00 (0.00-0.79) |" in table
    page = sp.sweep_page(rows, sp.FRICTION, "images/f.png", "python -m agents.evaluate", "d", "c")
    assert page.startswith("# Success against friction\n") and table in page
    assert "![success and grip against friction](images/f.png)" in page
    grip = sp.sweep_table(rows, sp.FRICTION, "grip")
    assert grip in page and grip.splitlines()[0] == table.splitlines()[0]
    scripted = next(r for r in rows if r["policy"] == "scripted" and r["friction"] == 0.0)
    low, high = scripted["grip_W_ci_low"], scripted["grip_W_ci_high"]
    mean = f"{scripted['grip_W_mean']:.2f} ({low:.2f}-{high:.2f})"
    assert f"| fig13 | scripted | planner | 1 | {mean} | n/a |" in grip  # no success at 0.3
    pytest.importorskip("matplotlib", reason="the viz extra draws the plot")
    sp.sweep_plot(tmp_path / "f.png", rows, sp.FRICTION)
    assert (tmp_path / "f.png").stat().st_size > 0


def test_rows_at_each_uncertainty_and_the_uncertainty_page(tmp_path):
    """Episodes at two vertex deviations (and two frictions): a row per pair, and an
    uncertainty page whose table has one success column per deviation, at the lowest
    friction."""
    noisy = [ep.Episode(**{**e.__dict__, "uncertainty": 0.02}) for e in EPISODES]
    noisy[0].success = False
    rough = [ep.Episode(**{**e.__dict__, "friction": 0.3}) for e in EPISODES + noisy]
    for e in rough:
        e.success = True
    rows = sm.summarize(EPISODES + noisy + rough, TEST_TIMES)
    plain = sm.summarize(EPISODES, TEST_TIMES)
    assert rows[: len(plain)] == plain
    assert [(r["friction"], r["uncertainty"]) for r in rows] == (
        [(0.0, 0.0)] * len(plain) + [(0.0, 0.02)] * len(plain)
        + [(0.3, 0.0)] * len(plain) + [(0.3, 0.02)] * len(plain)
    )  # fmt: skip
    assert "| fig13 (sigma 0.02) | scripted | planner | 1 | 0.00" in sm.markdown_table(rows)
    assert "| fig13 (mu 0.3, sigma 0.02) | scripted | planner | 1 | 1.00" in sm.markdown_table(rows)
    table = sp.sweep_table(rows, sp.UNCERTAINTY)
    assert table.splitlines()[0] == "| suite | policy | test time | n | sigma = 0 | sigma = 0.02 |"
    assert "| fig13 | scripted | planner | 1 | 1.00 (0.21-1.00) | 0.00 (0.00-0.79) |" in table
    page = sp.sweep_page(
        rows, sp.UNCERTAINTY, "images/u.png", "python -m agents.evaluate", "d", "c"
    )
    assert page.startswith("# Success against shape uncertainty\n") and table in page
    assert "![success and grip against shape uncertainty](images/u.png)" in page


def test_an_episode_at_an_uncertainty_plays_the_perturbed_env():
    """``run_episode(uncertainty=...)`` records the level and plays the env made with it:
    the planner's episode differs from the exact shape's."""
    spec = next(s for s in ep.default_policies([], []) if s.kind == "scripted")
    exact = ep.run_episode(spec, "bundled", "fig13", 0, 40)
    noisy = ep.run_episode(spec, "bundled", "fig13", 0, 40, uncertainty=0.02)
    assert (exact.uncertainty, noisy.uncertainty) == (0.0, 0.02)
    assert noisy.ret != exact.ret
