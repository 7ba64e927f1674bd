# Shared set-up of the Python module's tests: where the fixtures, the CLI and the sources are (ctest passes them in
# the environment, as CMake's UPLVSM_FIXTURES / UPLVSM_CLI / UPLVSM_SOURCE_DIR for the C++ tests).
import os
import pathlib

import pytest

REPO = pathlib.Path(os.environ.get("UPLVSM_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
FIXTURES = pathlib.Path(os.environ.get("UPLVSM_FIXTURES", REPO.parent / "shared" / "fixtures"))
CLI = os.environ.get("UPLVSM_CLI", str(REPO / "build" / "uplvsm"))
OFFICIAL = FIXTURES / "official_uplvsm"


@pytest.fixture(scope="session")
def official_io():
    import uplvsm
    return uplvsm.io.read_safetensors(str(OFFICIAL / "io.safetensors"))


@pytest.fixture(scope="session")
def official_model():
    import uplvsm
    return uplvsm.load(str(OFFICIAL / "checkpoint.pt"))
