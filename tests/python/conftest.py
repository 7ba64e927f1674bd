# Shared set-up of the Python module's tests: where the fixtures, the CLI and the sources are (ctest passes them in
# the environment, as CMake's UPLVSM_FIXTURES / UPLVSM_CLI / UPLVSM_SOURCE_DIR for the C++ tests).
import os
import pathlib

import pytest

REPO = pathlib.Path(os.environ.get("UPLVSM_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
FIXTURES = pathlib.Path(os.environ.get("UPLVSM_FIXTURES", REPO.parent / "shared" / "fixtures"))
CLI = os.environ.get("UPLVSM_CLI", str(REPO / "build" / "uplvsm"))
OFFICIAL = FIXTURES / "official_uplvsm"


def missing_fixtures():
    """Why the reference fixture pack (outside this repository) cannot be used, or None when its directory exists."""
    if FIXTURES.is_dir():
        return None
    return (f"reference fixture pack not found: {FIXTURES} (configure with -DUPLVSM_FIXTURES=DIR; what it holds and "
            'how it is made: docs/development.md, "The reference fixture pack")')


def fixtures_required():
    """CI runs every test: there a missing pack fails instead of skipping (as tests/test_util.h)."""
    return os.environ.get("CI") in ("true", "1") or os.environ.get("UPLVSM_REQUIRE_FIXTURES") == "1"


@pytest.fixture(scope="session")
def fixture_pack():
    """The pack's directory; skips the test (fails it under CI) when the pack is absent."""
    why = missing_fixtures()
    if why:
        (pytest.fail if fixtures_required() else pytest.skip)(why)
    return FIXTURES


# For a test that reads the pack directly (the fixtures below check it themselves).
needs_fixtures = pytest.mark.usefixtures("fixture_pack")


@pytest.fixture(scope="session")
def official_io(fixture_pack):
    import uplvsm
    return uplvsm.io.read_safetensors(str(OFFICIAL / "io.safetensors"))


@pytest.fixture(scope="session")
def official_model(fixture_pack):
    import uplvsm
    return uplvsm.load(str(OFFICIAL / "checkpoint.pt"))
