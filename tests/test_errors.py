"""The one wording of an unknown name (frictionuq.errors.unknown), used by the campaign and
workflow files, the fit configuration, the priors, the parameters, effects, units and ground
motions: the name, the closest known one when there is one, and the known names."""
import pytest

from frictionuq import params, units
from frictionuq.cli import main
from frictionuq.errors import InputError, unknown
from frictionuq.infer.config import FitConfig


def test_the_closest_name_is_suggested_ignoring_case():
    assert unknown("key", "knd", ["id", "file", "kind"]) == \
        "unknown key 'knd' (did you mean 'kind'?); known: id, file, kind"
    assert unknown("force unit", "kn", ["N", "kN", "lbf"]) == \
        "unknown force unit 'kn' (did you mean 'kN'?); known: N, kN, lbf"
    assert unknown("force unit", "newton", ["N", "kN"]) == "unknown force unit 'newton'; known: N, kN"


@pytest.mark.parametrize("call,message", [
    (lambda: units.factor("force", "kn"), "unknown force unit 'kn' (did you mean 'kN'?)"),
    (lambda: params.check_value("fc_fw", 1.0), "unknown parameter 'fc_fw' (did you mean 'fc_fwd'?)"),
    (lambda: params.check_effects({"thermal": {}}), "unknown effect 'thermal' (did you mean 'thermal_fade'?)"),
    (lambda: params.check_effects({}, model="lugr"), "unknown model 'lugr' (did you mean 'lugre'?)"),
    (lambda: FitConfig(sampler={"max_step": 3}), "sampler: unknown field 'max_step' (did you mean 'max_steps'?)"),
    (lambda: FitConfig(priors={"k2": {"dist": "uniform", "lower": 1, "uper": 2}}),
     "prior of 'k2': unknown key 'uper' (did you mean 'upper'?); known: dist, lower, upper, mu, sd"),
])
def test_library_refusals_share_the_wording(call, message):
    with pytest.raises(ValueError) as e:
        call()
    assert message in str(e.value) and "; known: " in str(e.value)


def test_a_campaign_key_typo_is_named_with_its_fix(tmp_path, capsys):
    (tmp_path / "campaign.toml").write_text(
        'name = "c"\n[units]\ntime = "s"\ndisplacement = "m"\nforce = "N"\napplied = "N"\n'
        '[[tests]]\nid = "a"\nfile = "a.csv"\napplied = 1\nknd = "harmonic"\n')
    assert main(["table", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "tests[0]: unknown key 'knd' (did you mean 'kind'?)" in err, err
    assert isinstance(InputError("x"), ValueError)
