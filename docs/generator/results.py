"""The results pages: :data:`RESULTS` names each page, its title in the nav, its data file
and its writer; :func:`result_pages` writes every ``docs/results/*.md`` whose data file
exists, each checked against :data:`~generator.common.SCHEMAS` first.
"""
from __future__ import annotations

from .common import _load, SCHEMAS
from .results_finer_grids import finer_grids_page
from .results_identification import identification_page
from .results_fading import fading_gain_block
from .results_handover import handover_block, joint_handover_block
from .results_leaderboard import fuzzy_designs_page, leaderboard_page
from .results_learners import learners_page
from .results_learning import learning_page
from .results_mismatch import mismatch_page
from .results_performance import performance_page
from .results_reproduction import reproduction_page
from .results_round_off import round_off_page
from .results_scaling import scaling_page


#: Results pages: (page, title in the nav, data file, writer).
RESULTS = (
    ("results/reproduction.md", "Reproduction", "docs/data/reproduce.json", reproduction_page),
    ("results/mismatch.md", "Model mismatch and robustness", "renders/mismatch/report.json",
     mismatch_page),
    ("results/learning.md", "Learning", "renders/learning/learning.json", learning_page),
    ("results/scaling.md", "Scaling", "renders/scaling/scaling.json", scaling_page),
    ("results/learners.md", "Learners on N links", "renders/learners/learners.json",
     learners_page),
    ("results/performance.md", "Performance", "benchmarks/results.json", performance_page),
    ("results/leaderboard.md", "Leaderboard", "renders/leaderboard/leaderboard.json",
     leaderboard_page),
    ("results/fuzzy-designs.md", "Fuzzy designs", "renders/leaderboard/leaderboard.json",
     lambda report: fuzzy_designs_page(report) + fading_gain_block()
     + handover_block(report) + joint_handover_block()),
    ("results/round-off.md", "Round-off and ties",
     "renders/tie_sensitivity/tie_sensitivity.json", round_off_page),
    ("results/finer-grids.md", "Finer grids", "renders/grid_study/grid_study.json",
     finer_grids_page),
    ("results/identification.md", "Identification",
     "renders/identification/identification.json", identification_page),
)


def result_pages() -> dict:
    return {page: write(data) for page, _, rel, write in RESULTS
            if (data := _load(rel, SCHEMAS[rel])) is not None}
