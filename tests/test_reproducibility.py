"""The platform facts in every artifact's provenance, and the portable profile (FAMARL_REPRO=portable)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
import torch

from famarl_cli.core.reproducibility import platform_facts

NATIVE = torch.backends.cpu.get_cpu_capability()


def _famarl(*args, env: dict, cwd) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "famarl_cli", *map(str, args)],
        env={**os.environ, **env},
        cwd=cwd,
        capture_output=True,
        text=True,
        check=False,
    )


def test_platform_facts_name_what_decides_the_floats():
    facts = platform_facts()
    assert facts["profile"] == "native"
    assert facts["torch"] == torch.__version__ and facts["cpu_capability"] == NATIVE
    assert facts["threads"] == torch.get_num_threads() and isinstance(facts["mkldnn"], bool)
    assert isinstance(facts["numpy"], str) and isinstance(facts["knobs"], dict)


@pytest.mark.slow
@pytest.mark.parametrize("profile", ["native", "portable"])
def test_artifacts_record_their_profile(profile, tmp_path, segments_file):
    result = _famarl("favae", "calibrate", "--segments", segments_file, "--epochs", 2, "--out", tmp_path / "c.json",
                     env={"FAMARL_REPRO": profile}, cwd=tmp_path)  # fmt: skip
    assert result.returncode == 0, result.stderr
    facts = json.loads((tmp_path / "c.json").read_text())["provenance"]["platform"]
    assert facts["profile"] == profile and facts["threads"] == 1
    if profile == "portable":
        assert facts["cpu_capability"] in ("AVX2", "DEFAULT") and facts["mkldnn"] is False
        assert facts["knobs"]["MKL_CBWR"] == "COMPATIBLE" and facts["knobs"]["ATEN_CPU_CAPABILITY"] == "avx2"


def test_a_portable_profile_set_too_late_is_refused(tmp_path):
    if not NATIVE.startswith("AVX512"):
        pytest.skip("on this CPU torch's kernels are AVX2 at most, so loading it early changes nothing")
    # torch fixes its kernels' instruction set at its first operation: after that the profile cannot hold.
    code = "import torch; torch.ones(3).softmax(0); import famarl_cli.core.reproducibility as r; r.one_thread()"
    done = subprocess.run(
        [sys.executable, "-c", code], env={**os.environ, "FAMARL_REPRO": "portable"}, capture_output=True, text=True
    )
    assert done.returncode != 0 and "must be set before famarl (or torch) is imported" in done.stderr


@pytest.mark.slow
def test_an_unknown_profile_is_a_usage_error(tmp_path):
    result = _famarl("train", "--agent", "ppo", "--steps", 10, env={"FAMARL_REPRO": "fast"}, cwd=tmp_path)
    assert result.returncode == 2
    message = result.stderr.strip()
    assert message.startswith("error: FAMARL_REPRO='fast'; expected one of native, portable")
    assert "\n" not in message and message.endswith("train --help`)")
