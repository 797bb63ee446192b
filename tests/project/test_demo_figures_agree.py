"""The README, the demo's results page and the demo's summary file give the same time and the
same number of training rows (the summary file is the run the page's tables come from)."""

import json
import re

from tests.helpers import ROOT

SUMMARY = json.loads((ROOT / "docs" / "demo" / "summary.json").read_text())


def spaced(n: int) -> str:
    """52000 → '52 000', as the pages write thousands."""
    return f"{n:,}".replace(",", " ")


def test_the_readme_gives_the_summarys_time_and_stages():
    readme = (ROOT / "README.md").read_text()
    sentence = re.search(r"The demo takes .*?\.(?=\s)", readme.replace("\n", " ")).group(0)
    assert f"({round(SUMMARY['wall_time_s'])} s, the `wall_time_s`" in sentence, sentence
    for stage, seconds in SUMMARY["stage_times_s"].items():
        assert f"{stage} {round(seconds)} s" in sentence, (stage, sentence)


def rendered_demo_page() -> str:
    """The demo's results page as the docs build renders it (its figures from result files)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("result_files",
                                                  ROOT / "docs" / "hooks" / "result_files.py")
    hook = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hook)
    return hook.render((ROOT / "docs" / "results" / "demo.md").read_text(), "results/demo.md")


def test_the_results_page_gives_the_summarys_rows_and_time():
    page = rendered_demo_page().replace("\n", " ")
    rows = spaced(SUMMARY["training_rows"])
    said = re.findall(r"(?:on the same|training data are) (\d[\d ]*\d) rows", page)
    assert said and set(said) == {rows}, said
    timed = re.search(r"Result of `ftdrake demo[^`]*`: (\d+) s", page).group(1)
    assert int(timed) == round(SUMMARY["wall_time_s"])
    for stage, seconds in SUMMARY["stage_times_s"].items():
        assert f"{stage} {round(seconds)} s" in page, stage
