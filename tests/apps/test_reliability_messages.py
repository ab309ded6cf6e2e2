"""Messages that say what is wrong: a non-boolean flag to simulate(), a --set name whose
component does not exist in a one-component scenario, an SSP's FMUs named inside the archive."""
from __future__ import annotations


import pytest
from click.testing import CliRunner

import deltafmi
from deltafmi.apps.cli import main

SCENARIO = """\
experiment: {stop: 0.1, step: 0.01}
components:
  osc: {source: 'deltafmi.models:Oscillator', interface: ME}
outputs: [osc.x]
"""


@pytest.mark.parametrize("option", ["verbose", "allow_nan", "realtime"])
def test_simulate_refuses_a_flag_that_is_not_a_boolean(option):
    with pytest.raises(deltafmi.BadInput, match=rf"^simulate\({option}='yes'\): expected True or False$"):
        deltafmi.simulate("delta_tracking", stop=0.01, **{option: "yes"})


def test_a_set_name_of_no_component_says_so_in_a_one_component_scenario(tmp_path):
    path = tmp_path / "osc.yaml"
    path.write_text(SCENARIO)
    done = CliRunner().invoke(main, ["run", str(path), "--set", "nocomp.k=1"])
    assert done.exit_code == 2
    assert done.output.strip().splitlines()[-1] == (
        "--set nocomp.k: error: component 'osc': parameter 'nocomp.k': no such variable in the FMU (nor is "
        "'nocomp' a component: the scenario's one component is 'osc')")


def test_validate_of_an_ssp_names_its_fmus_inside_the_archive(tmp_path):
    archive = tmp_path / "dt.ssp"
    assert CliRunner().invoke(main, ["export-ssp", "delta_tracking", "-o", str(archive)]).exit_code == 0
    done = CliRunner().invoke(main, ["validate", str(archive)])
    assert done.exit_code == 0, done.output
    assert f"  plant: ME DeltaRobot, FMI 2.0 ({archive}: resources/DeltaRobot.fmu)" in done.output.splitlines()
    assert "deltafmi-ssp-" not in done.output  # no folder that is gone by now


def test_the_no_compiler_message_of_a_wheel_does_not_send_its_user_to_the_wheel(tmp_path, monkeypatch):
    from deltafmi import toolchain
    from_clone = toolchain.no_compiler_message("cc")
    assert from_clone.endswith("the packaged models need none when deltafmi is installed from its wheel, which "
                               "carries them prebuilt")
    monkeypatch.setattr(toolchain, "PREBUILT_DIR", tmp_path)  # where an installed wheel has its prebuilt layer
    assert toolchain.no_compiler_message("cc") == (
        "building needs a C compiler (cc not found; install gcc or set CC); this installation's prebuilt pieces "
        "cover the packaged models as shipped, not an edited copy of one or a component of your own")
