"""Where the tests find the repository: its root, the shipped scenarios, the test FMU sources."""

from pathlib import Path

TESTS_DIR = Path(__file__).resolve().parents[1]
REPO_ROOT = TESTS_DIR.parent
SCENARIOS_DIR = REPO_ROOT / "scenarios"
TEST_FMUS_DIR = TESTS_DIR / "fmus"
