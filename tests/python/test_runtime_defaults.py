# What `import uplvsm` does to the process (python/uplvsm/__init__.py): intra-op threads = the cores this process
# may use unless the user chose them, and one warning when the loaded BLAS is slower than the CPU allows. Each case
# runs in a fresh interpreter, since both happen once, on import.
import os
import subprocess
import sys

import pytest

PROBE = """
import warnings
warnings.simplefilter("always")
with warnings.catch_warnings(record=True) as caught:
    import uplvsm
import torch
blas = [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning) and "BLAS" in str(w.message)]
print(torch.get_num_threads())
print(len(blas))
print(blas[0] if blas else "")
"""


def run(env_changes):
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "UPLVSM_RUNTIME")}
    env.update(env_changes)
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True).stdout
    threads, warnings, message = out.split("\n")[:3]
    return int(threads), int(warnings), message


def plain_torch_threads(env_changes):
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    env.update(env_changes)
    code = "import torch; print(torch.get_num_threads())"
    return int(subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout)


def test_import_uses_every_available_core():
    threads, warnings, _ = run({})
    assert threads == len(os.sched_getaffinity(0))
    assert warnings <= 1  # at most one BLAS warning, whatever the machine


def test_a_users_thread_choice_stays():
    assert run({"OMP_NUM_THREADS": "1"})[0] == 1


def test_opt_out_leaves_torch_as_it_was():
    assert run({"UPLVSM_RUNTIME": "off"})[0] == plain_torch_threads({})


def cpu_flags():
    try:
        with open("/proc/cpuinfo") as f:
            return next(line for line in f if line.startswith("flags")).split()
    except (OSError, StopIteration):
        return []


@pytest.mark.skipif(not {"avx2", "fma"} <= set(cpu_flags()), reason="the CPU has no AVX2: Prescott is its best")
def test_one_warning_names_a_coretype_that_holds_openblas_back():
    _, warnings, message = run({"OPENBLAS_CORETYPE": "Prescott"})
    assert warnings == 1
    assert "OPENBLAS_CORETYPE=Prescott in the environment" in message
    assert "unset OPENBLAS_CORETYPE" in message
