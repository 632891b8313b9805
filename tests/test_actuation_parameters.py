"""Each motor model's parameter table is the single source of every parameter's name, unit, plausible range, default
and fit bounds: the model classes, motors.yaml, params.json, the fit vector, the perturbations and docs/sysid.md all
follow it."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
import yaml

from toddlerbot.actuation.appendix import ActuatorParams
from toddlerbot.actuation.catalogue import DEFAULT_CATALOGUE, default_catalogue, load_catalogue
from toddlerbot.actuation.dc_motor import DCMotorParams
from toddlerbot.actuation.motor_models import MOTOR_MODELS, all_parameters, motor_model
from toddlerbot.actuation.params_file import load_params
from toddlerbot.errors import ParamsError, SpecError
from toddlerbot.sysid.params import (
    fit_models,
    from_unit,
    save_params,
    search_range,
    searched_as,
    searched_value,
    to_unit,
)

PARAMETERS = all_parameters()


def parameters_of(model: str) -> tuple:
    return motor_model(model).parameters

DOCS = Path(__file__).parents[1] / "docs" / "sysid.md"


@pytest.mark.parametrize("model", ["appendix", "dc_motor"])
def test_each_models_fields_are_its_table_rows_in_order(model: str) -> None:
    fields = dataclasses.fields(motor_model(model))
    assert [f.name for f in fields] == [p.name for p in parameters_of(model)]
    defaults = {f.name: f.default for f in fields if f.default is not dataclasses.MISSING}
    assert defaults == {p.name: p.default for p in parameters_of(model) if p.default is not None}
    assert all(f.type is float for f in fields)


def test_every_row_belongs_to_a_model_and_the_two_models_share_the_passive_terms() -> None:
    classes = [motor_model(name) for name in MOTOR_MODELS.names()]
    assert set(PARAMETERS) == {f.name for cls in classes for f in dataclasses.fields(cls)}
    shared = [p.name for p in PARAMETERS.values() if all(p in cls.parameters for cls in classes)]
    assert shared == ["damping", "armature", "frictionloss", "load_friction"]
    assert len(PARAMETERS) == 17


def test_motors_yaml_names_only_table_parameters_and_every_value_is_plausible() -> None:
    raw = yaml.safe_load(DEFAULT_CATALOGUE.read_text())
    for name, entry in raw.items():
        fields = dict(entry["actuator"])
        model = fields.pop("model", "appendix")
        assert set(fields) <= {p.name for p in parameters_of(model)}, name
        for field, value in fields.items():
            assert 0 <= value <= PARAMETERS[field].maximum, (name, field)


def test_fit_bounds_contain_the_catalogue_values() -> None:
    """Every value motors.yaml gives lies in its fit bounds (for q_dot_max: the span above q_dot_tau_max; for
    tau_q_dot_max: the fraction of tau_max), except the unidentified XL330-M077's speeds, scaled from the XC330 by
    the no-load speed (a fit of it starts clipped onto the bounds)."""
    raw = yaml.safe_load(DEFAULT_CATALOGUE.read_text())
    outside = {}
    for name, model in default_catalogue().models.items():
        for field in set(raw[name]["actuator"]) - {"model"}:
            value, p = searched_value(field, model.actuator), PARAMETERS[field]
            if not p.lower <= value <= p.upper:
                outside[(name, field)] = round(value, 6)
    assert outside == {("XL330-M077-T", "q_dot_tau_max"): 9.7, ("XL330-M077-T", "q_dot_max"): 25.3}
    assert (PARAMETERS["q_dot_tau_max"].upper, PARAMETERS["q_dot_max"].upper) == (8.0, 20.0)


def test_the_fit_vector_and_its_bounds_come_from_the_table() -> None:
    for name, p in PARAMETERS.items():
        assert search_range(name) == (p.lower, p.upper, p.log, p.unit)
    assert {name: searched_as(name) for name in PARAMETERS if searched_as(name)} == {
        "q_dot_max": " above q_dot_tau_max", "tau_q_dot_max": " x tau_max"}
    for fm in fit_models().values():
        names = (*fm.fitted, fm.gain_parameter, *fm.fixed)
        assert len(set(names)) == len(names), fm.name
        assert set(names) == {p.name for p in parameters_of(fm.params_class.model)}, fm.name
    # the unit cube maps onto the table's bounds: 0 -> lower, 1 -> upper, log-scaled ones at the geometric mean
    base = default_catalogue()["XC330"].actuator
    ends = from_unit([[0.0, 0.0, 0.5], [1.0, 1.0, 0.5]], ("damping", "q_dot_tau_max", "kd_min"), base)
    assert ends.fields["damping"].tolist() == pytest.approx([1e-4, 0.05])
    assert ends.fields["q_dot_tau_max"].tolist() == pytest.approx([0.0, 8.0])
    assert ends.fields["kd_min"].tolist() == pytest.approx([(0.01 * 2.0) ** 0.5] * 2)
    # q_dot_max is searched as its span above q_dot_tau_max: 4.7 of 0.2..20 rad/s
    assert to_unit(base, ("q_dot_max",)).tolist() == pytest.approx([(6.5 - 1.8 - 0.2) / 19.8])


@pytest.mark.parametrize("motor", ["XC330", "XL330-M288"])
def test_params_json_holds_exactly_the_models_table_parameters(tmp_path: Path, motor: str) -> None:
    params = default_catalogue()[motor].actuator
    path = save_params(tmp_path / "p.json", motor, params, (), {})
    actuator = json.loads(path.read_text())["actuator"]
    assert list(actuator) == ["model", *(p.name for p in parameters_of(params.model))]
    assert load_params(path)[1] == params


@pytest.mark.parametrize(("motor", "field", "value", "expected"), [
    ("XM430", "kd_min", 150, "kd_min must be at most 100, got 150 (motor XM430-W210)"),
    ("XC330", "kp_scale", 0, "kp_scale must be > 0, got 0 (motor XC330-T288)"),
    ("XL330-M288", "load_friction", 1.0, "load_friction must be below 1, got 1 (motor XL330-M288-T)"),
    ("XL330-M288", "pwm_exponent", 3.5, "pwm_exponent must be at most 3, got 3.5 (motor XL330-M288-T)"),
    ("XC330", "stiction", "lots", "stiction must be a finite number >= 0, got 'lots' (motor XC330-T288)"),
])
def test_an_out_of_range_params_json_value_is_refused_in_one_line(tmp_path: Path, motor: str, field: str,
                                                                  value: object, expected: str) -> None:
    path = tmp_path / "p.json"
    model = default_catalogue()[motor].actuator.model
    path.write_text(json.dumps({"motor": motor, "actuator": {"model": model, field: value}}))
    with pytest.raises(ParamsError) as info:
        load_params(path)
    assert str(info.value) == f"{path}: {expected}"


def test_an_out_of_range_motors_yaml_value_is_refused_in_one_line(tmp_path: Path) -> None:
    path = tmp_path / "motors.yaml"
    path.write_text(DEFAULT_CATALOGUE.read_text().replace("kd_min: 0.384", "kd_min: 150", 1))
    with pytest.raises(SpecError) as info:
        load_catalogue(path)
    assert str(info.value) == f"{path}: motor model 'XC330-T288': kd_min must be at most 100, got 150"


def test_the_checks_are_the_tables() -> None:
    base = default_catalogue()["XC330"].actuator
    assert base.replace(load_friction=0.99).load_friction == 0.99  # below_maximum: up to, not at, 1
    with pytest.raises(ValueError, match=r"^tau_brake must be at most 1000, got 1001$"):
        base.replace(tau_brake=1001.0)
    with pytest.raises(ValueError, match=r"^q_dot_max \(1.0\) must exceed q_dot_tau_max \(1.8\)$"):
        base.replace(q_dot_max=1.0)  # the one relation between parameters, kept by the class
    with pytest.raises(ValueError, match=r"^stall_torque must be > 0, got 0.0$"):
        default_catalogue()["XL330-M288"].actuator.replace(stall_torque=0.0)
    assert isinstance(base, ActuatorParams) and not isinstance(base, DCMotorParams)


def _docs_rows() -> dict[str, list[str]]:
    """The rows of docs/sysid.md's parameter table: name -> [unit, fit bounds, scale, plausible max, default, model,
    meaning]."""
    text = DOCS.read_text()
    table = text[text.index("| parameter | unit | fit bounds |"):]
    rows = {}
    for line in table.splitlines()[2:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        rows[cells[0]] = cells[1:]
    return rows


def test_docs_show_the_table() -> None:
    rows = _docs_rows()
    assert list(rows) == list(PARAMETERS)
    for name, p in PARAMETERS.items():
        span = f"{p.lower:g} - {p.upper:g}"
        bounds = (f"{p.span_above} + ({span})" if p.span_above else f"({span}) x {p.fraction_of}" if p.fraction_of
                  else span)
        maximum = f"< {p.maximum:g}" if p.below_maximum else f"{p.maximum:g}"
        default = "-" if p.default is None else f"{p.default:g}"
        having = [m for m in MOTOR_MODELS.names() if p in motor_model(m).parameters]
        model = "both" if len(having) == 2 else having[0]
        expected = [p.unit, bounds, "log" if p.log else "linear", maximum, default, model, p.doc]
        assert rows[name] == expected, name
