"""Typed schema of a scenario file (pydantic v2, extra fields forbidden everywhere).

`Scenario` is the validated document plus what the master asks of it: tick
counts, per-component periods in ticks, plant parameters with uncertainty
applied, the Python components (sources included) and the FMUs. Load files
with `cosim.scenario.loader.load_scenario`, which adds YAML line numbers to errors.
"""

from __future__ import annotations

import fnmatch
import math
import re
from pathlib import Path
from typing import Annotated, Any, Literal, Union

from pydantic import (AfterValidator, BaseModel, BeforeValidator, ConfigDict, Discriminator, Field,
                      FiniteFloat, NonNegativeFloat, PositiveFloat, PrivateAttr, Tag,
                      ValidationInfo, model_serializer,
                      model_validator)

from cosim.errors import Problem, ScenarioError, UserError
from cosim.scenario.checks import BUILTIN_FMUS, semantic_problems, whole_ticks
from cosim.scenario.loops import locate_loop
from cosim.scenario.roles import MetricRoles
from cosim.scenario.sources import SOURCE_CLASSES, SourceSpec
from cosim.scenario.yaml_lines import LineMap, format_path

# strict: a bool or a string is never read as a number ("duration: true" is an error)
STRICT = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)
RUN_NAME = re.compile(r"^[A-Za-z0-9._-]{1,100}$")
PYTHON_CLASS = r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*:[A-Za-z_][A-Za-z0-9_]*$"
ENDPOINT = r"^[A-Za-z_][A-Za-z0-9_]*(\.\S.*)?$"


#: an [x, y] pair: YAML gives a list, which strict mode would refuse as a tuple
XYPair = Annotated[tuple[FiniteFloat, FiniteFloat], Field(strict=False)]


def _run_name(value: Any) -> Any:
    """A run name becomes a folder name: letters, digits, '-', '_', '.', at most 100."""
    if isinstance(value, str) and (not RUN_NAME.match(value) or value in (".", "..")):
        raise ValueError("must be a safe file name: letters, digits, '-', '_', '.' "
                         f"(at most 100 characters, not . or ..), got {value[:120]!r}"
                         + (f" ({len(value)} characters)" if len(value) > 100 else ""))
    return value


class Uncertainty(BaseModel):
    """Plant parameter error: the plant gets value * scale + offset."""

    model_config = STRICT
    scale: float = Field(1.0, description="factor on the nominal value, 1")
    offset: float = Field(0.0, description="added after the factor, in the parameter's own unit")

    def apply(self, value: float) -> float:
        """The perturbed value of a nominal parameter value."""
        return value * self.scale + self.offset


class SolverSpec(BaseModel):
    """How the master integrates a Model Exchange FMU."""

    model_config = STRICT
    method: Literal["cvode", "rk4", "euler"] = Field("cvode", description=(
        "integrator: 'cvode' (SUNDIALS CVode, BDF, variable step, state events located), "
        "'rk4' or 'euler' (fixed step)"))
    rtol: PositiveFloat = Field(1e-5, description="relative tolerance of cvode, 1")
    atol: PositiveFloat | None = Field(None, description=(
        "absolute tolerance of cvode, in each state's unit (null: rtol times each state's "
        "nominal)"))
    max_step: PositiveFloat | None = Field(None, description=(
        "cvode's largest step, or the step of rk4 and euler, s (null: duration / 50 for cvode, "
        "the component's period for rk4 and euler)"))


class FmuSpec(BaseModel):
    """A component that is an FMU (built-in name or path to a .fmu)."""

    model_config = STRICT
    fmu: str = Field(min_length=1, description=(
        "a built-in model's name (a folder of fmus/, e.g. Vehicle8DOF, Bicycle) or the path to "
        "a .fmu, relative to the scenario file"))
    period: PositiveFloat | None = Field(None, description=(
        "time between two steps, a whole multiple of tick, s (null: every master tick)"))
    parameters: dict[str, FiniteFloat] = Field({}, description=(
        "parameter start values by canonical name, each in the FMU variable's unit"))
    uncertainty: dict[str, Uncertainty] = Field({}, description=(
        "model error per parameter: the plant gets value * scale + offset"))
    variables: dict[str, str] = Field({}, description=(
        "canonical name -> the FMU's own variable name (for a foreign FMU)"))
    host: str = Field("local", min_length=1, description="'local' or the name of a worker "
                                                         "that runs the FMU")
    deadline: PositiveFloat | None = Field(None, description=(
        "time an FMI call may take, wall clock s (null: the run's --deadline)"))
    isolate: bool = Field(False, description=(
        "run the FMU in a local process of its own, so its crash or hang cannot touch the master"))
    log: bool = Field(False, description=(
        "send the FMU's log messages to run.log (warnings and errors also to the terminal)"))
    interface: Literal["co_simulation", "model_exchange"] | None = Field(None, description=(
        "FMI interface to use (null: co-simulation when the FMU offers it, else model exchange)"))
    solver: SolverSpec | None = Field(None, description=(
        "integrator of a Model Exchange FMU (null: cvode with its defaults)"))


class PythonSpec(BaseModel):
    """A component that is a Python class (a cosim.component.Component subclass)."""

    model_config = STRICT
    python: str = Field(pattern=PYTHON_CLASS, description=(
        "the component class, 'package.module:Class' (a cosim.component.Component subclass)"))
    period: PositiveFloat | None = Field(None, description=(
        "time between two steps, a whole multiple of tick, s (null: the class's default_period, "
        "else every master tick)"))
    parameters: dict[str, Any] = Field({}, description=(
        "keyword arguments of the class; for a shipped class, typed and described by its "
        "parameter model"))
    host: str = Field("local", min_length=1, description="'local' (the master's host), 'inproc' "
                                                         "(the master's own process) or the name of a "
                                                         "worker that runs the component")
    deadline: PositiveFloat | None = Field(None, description=(
        "time a step may take in-process, wall clock s (null: the run's --deadline)"))


def _component_tag(value: Any) -> str | None:
    """'<fmu>' or '<python>' by which key the component has; None if both or neither."""
    if isinstance(value, (FmuSpec, PythonSpec)):
        return "<fmu>" if isinstance(value, FmuSpec) else "<python>"
    if not isinstance(value, dict) or ("fmu" in value) == ("python" in value):
        return None
    return "<fmu>" if "fmu" in value else "<python>"


ComponentSpec = Annotated[
    Union[Annotated[FmuSpec, Tag("<fmu>")], Annotated[PythonSpec, Tag("<python>")]],
    Discriminator(
        _component_tag,
        custom_error_type="component_kind",
        custom_error_message="a component needs exactly one of 'fmu:' (built-in name or "
                             "path to a .fmu) or 'python:' (module:Class)",
    ),
]


def _drop_none(dumped: Any, keys: tuple[str, ...]) -> Any:
    """A dump without the optional fields of `keys` that are None (dumps stay as they were)."""
    if isinstance(dumped, dict):
        for key in keys:
            if dumped.get(key, 0) is None:
                del dumped[key]
    return dumped


def _parse_connection(value: Any) -> Any:
    """Accept the short string forms "a -> b" and "a.x -> b.y"."""
    if not isinstance(value, str):
        return value
    parts = value.split("->")
    if len(parts) != 2:
        raise ValueError(f"connection {value!r} must read 'source -> destination'")
    return {"from": parts[0].strip(), "to": parts[1].strip()}


class Connection(BaseModel):
    """One connection: `component.port -> component.port`, or the short form
    `component -> component` (every output feeding the input of the same name)."""

    model_config = ConfigDict(extra="forbid", validate_by_name=True, validate_by_alias=True,
                              serialize_by_alias=True, strict=True)
    src: str = Field(alias="from", pattern=ENDPOINT, description=(
        "source: 'component' (every output) or 'component.port'"))
    dst: str = Field(alias="to", pattern=ENDPOINT, description=(
        "destination: 'component' (the inputs named as the source's outputs) or 'component.port'"))
    # a feedback edge needs one tick; the master takes no more
    delay: int = Field(0, ge=0, le=1, description="master ticks of delay on this edge (1 breaks "
                                                  "a feedback loop), ticks")
    scale: FiniteFloat | None = Field(None, description=(
        "the input reads scale * x (+ offset), 1 (null: 1; a.x -> b.y form, scalar signals)"))
    offset: FiniteFloat | None = Field(None, description=(
        "added after scale, in the input's unit (null: 0; a.x -> b.y form, scalar signals)"))
    convert: Literal["float"] | None = Field(None, description=(
        "'float': accept types whose conversion is not exact (Float64 -> Integer input, "
        "Int64 -> Float64); an integer or Boolean input then takes integer values only, else "
        "the run fails (null: exact conversions only)"))

    @model_validator(mode="before")
    @classmethod
    def _short_string(cls, value: Any) -> Any:
        return _parse_connection(value)

    @model_validator(mode="after")
    def _same_form(self) -> Connection:
        if (self.src_port is None) != (self.dst_port is None):
            raise ValueError(f"connection {self.src} -> {self.dst}: either both sides name a "
                             "port (a.x -> b.y) or neither (a -> b)")
        if self.src_port is None and (self.scale is not None or self.offset is not None):
            raise ValueError(f"connection {self.src} -> {self.dst}: scale and offset need "
                             "the a.x -> b.y form")
        return self

    @model_serializer(mode="wrap")
    def _without_unset_transform(self, handler: Any) -> Any:
        return _drop_none(handler(self), ("scale", "offset", "convert"))

    @property
    def src_component(self) -> str:
        """Component name of the source side."""
        return self.src.split(".", 1)[0]

    @property
    def src_port(self) -> str | None:
        """Port name of the source side (None in the short form)."""
        parts = self.src.split(".", 1)
        return parts[1] if len(parts) == 2 else None

    @property
    def dst_component(self) -> str:
        """Component name of the destination side."""
        return self.dst.split(".", 1)[0]

    @property
    def dst_port(self) -> str | None:
        """Port name of the destination side (None in the short form)."""
        parts = self.dst.split(".", 1)
        return parts[1] if len(parts) == 2 else None

    @property
    def is_short(self) -> bool:
        """True for the `a -> b` form that matches ports by name."""
        return self.src_port is None


ConnectionEntry = Annotated[
    Connection, BeforeValidator(_parse_connection, json_schema_input_type=Union[str, Connection])
]


def _with_csv(formats: list[str]) -> list[str]:
    if "csv" not in formats:
        raise ValueError("must include 'csv' (the analysis, `cosim recover` and the "
                         "supervisor read it); list 'parquet' beside it: [csv, parquet]")
    if len(set(formats)) != len(formats):
        raise ValueError(f"lists a format twice: {formats}")
    return formats


class RecordOutput(BaseModel):
    """How the recorded signals are written: the tick stride and the file formats."""

    model_config = STRICT
    every: Annotated[int, Field(ge=1, description=(
        "Record every N-th tick: the files hold ticks 0, N, 2N, ... and always the run's "
        "last tick (array signals: their rows at those ticks, and their last row). "
        "Integer >= 1, default 1 (every tick). The run's metrics are still computed "
        "from every tick."))] = 1
    format: Annotated[list[Literal["csv", "parquet"]], AfterValidator(_with_csv), Field(
        description=("Result files: 'csv' (signals.csv, arrays/*.csv; always written) and "
                     "optionally 'parquet' (signals.parquet, arrays/*.parquet, same rows "
                     "and float64 values, units in the field metadata; needs pyarrow, the "
                     "'parquet' extra). Default [csv].")
    )] = ["csv"]


class RecordSpec(RecordOutput):
    """Which signals to record: fnmatch globs over "component.signal"; mcap: also write run.mcap."""

    model_config = STRICT
    include: list[str] = Field(["*"], description=(
        "fnmatch globs over 'component.signal' of the signals to record"))
    exclude: list[str] = Field([], description="globs of signals not to record, "
                                               "though included")
    mcap: bool = Field(False, description=(   # cosim.foxglove.mcap_export
        "also write run.mcap (for Foxglove) beside signals.csv after the run"))

    def selects(self, signal: str) -> bool:
        """True if `signal` ("component.signal") matches an include and no exclude glob."""
        return (any(fnmatch.fnmatchcase(signal, g) for g in self.include)
                and not any(fnmatch.fnmatchcase(signal, g) for g in self.exclude))


class MetricsSpec(MetricRoles):
    """Settings of the run metrics (cosim.analysis.metrics): which component plays which role
    (cosim.scenario.roles), transient to skip, cones, body size."""

    model_config = STRICT
    skip_s: NonNegativeFloat = Field(0.0, description="initial transient left out of the "
                                                      "metrics, s")
    cones: list[XYPair] = Field([], description="cone positions [x, y] in world axes, m "
                                                "(cone strikes are counted)")
    vehicle_length: PositiveFloat = Field(4.5, description="body length, m")
    vehicle_width: PositiveFloat = Field(1.8, description="body width, m")
    vehicle_front: PositiveFloat | None = Field(None, description=(
        "CG to front bumper, m (null: half the length)"))
    figures: Literal["track", "manoeuvre", "following"] | None = Field(None, description=(
        "figure layout of the run (null: chosen from the run)"))


class Scenario(BaseModel):
    """A validated scenario; see the module docstring and cosim.scenario.loader for the format."""

    model_config = STRICT
    name: Annotated[str, Field(min_length=1, description=(
        "the run's name, also its results folder's: letters, digits, '-', '_', '.' "
        "(at most 100)")), AfterValidator(_run_name)]
    description: str = Field("", description="what the scenario shows, one line or a few")
    duration: PositiveFloat = Field(description="simulated time, a whole number of ticks, s")
    tick: PositiveFloat = Field(description="the master's base step; every period is a whole "
                                            "multiple of it, s")
    start_time: FiniteFloat | None = Field(None, description=(
        "simulation time at tick 0, s (null: the FMUs' DefaultExperiment start, else 0)"))
    # None once loaded, so that a loaded scenario's dump stands on its own
    system: str | None = Field(None, description=(
        "an .ssp (path relative to this file) whose FMU components and connections are merged "
        "in first (cosim.scenario.ssp)"))
    components: dict[str, ComponentSpec] = Field(min_length=1, description=(
        "the components by name (identifiers): each an FMU (fmu:) or a Python class (python:)"))
    sources: dict[str, SourceSpec] = Field({}, description=(
        "signal sources by name: each a component with one output 'value', of a kind"))
    connections: list[ConnectionEntry] = Field([], description=(
        "'a.x -> b.y', 'a -> b' (ports matched by name) or {from, to, delay, scale, offset}"))
    record: RecordSpec = Field(RecordSpec(), description="which signals go to signals.csv")
    metrics: MetricsSpec = Field(MetricsSpec(), description="settings of the run metrics "
                                                            "and figures")

    _file: Path | None = PrivateAttr(None)

    @model_serializer(mode="wrap")
    def _without_merged_system(self, handler: Any) -> Any:
        return _drop_none(handler(self), ("system",))  # dumps (manifests) stay as before
    _lines: LineMap = PrivateAttr(default_factory=LineMap)

    @model_validator(mode="after")
    def _cross_checks(self, info: ValidationInfo) -> Scenario:
        if info.context and info.context.get("deferred_checks"):
            return self  # load_scenario runs them itself, with line numbers
        problems = semantic_problems(self.model_dump(), None)
        if problems:
            raise ValueError("; ".join(f"{format_path(loc)}: {msg}" for loc, msg in problems))
        return self

    # ---- where things are in the file -------------------------------------------------
    @property
    def source_file(self) -> Path | None:
        """The YAML file this scenario was loaded from (None if built in memory)."""
        return self._file

    @property
    def base_dir(self) -> Path:
        """Folder that relative paths in the scenario resolve against."""
        return self._file.parent if self._file is not None else Path.cwd()

    def line_of(self, path: tuple[str | int, ...]) -> int | None:
        """1-based YAML line of a document path, e.g. ("connections", 2); None if unknown."""
        return self._lines.line_of(path)

    def problem(self, path: tuple[str | int, ...], message: str) -> Problem:
        """A Problem at a document path, with its line and any --set override noted."""
        override = self._lines.override_of(path)
        if override is not None:
            message += f" (set by --set {override})"
        return Problem(format_path(path), self.line_of(path), message)

    def where(self, path: tuple[str | int, ...], *also: tuple[str | int, ...]) -> str:
        """"FILE:LINE: PATH" for messages of other layers (FMU checks, wiring), with
        " (set by --set ...)" when an override put the value there.

        Args:
            path: the field the message is about.
            also: other fields its value derives from, each noted when an override
                set it: where(("duration",), ("tick",)) for a tick count gives
                "FILE:10: duration (tick set by --set tick=1e-300)".
        """
        where = Problem(format_path(path), self.line_of(path), "").format(self._file)
        override = self._lines.override_of(path)
        notes = "".join(self._lines.also_set(other) for other in also if other != path)
        return where.rstrip(": ") + (f" (set by --set {override})" if override else "") + notes

    def overrides_within(self, path: tuple[str | int, ...]) -> list[str]:
        """The --set texts that set `path`, an ancestor or a field under it."""
        return self._lines.overrides_within(path)

    def locate(self, error: BaseException) -> UserError | None:
        """An error another layer raised about the scenario as a whole, located in the
        file: an algebraic loop of the step order (cosim.engine.schedule) at the loop's
        connection, with its line and "(set by --set ...)" (cosim.scenario.loops);
        None for any other error (raise it as it is)."""
        return locate_loop(self, error)

    # ---- what the master asks ---------------------------------------------------------
    @property
    def total_ticks(self) -> int:
        """Number of master ticks in the run: duration / tick, exactly."""
        ticks = whole_ticks(self.duration, self.tick)
        if ticks is None:
            raise ScenarioError(self._file, [self.problem(
                ("duration",), f"duration {self.duration:g} s is not a whole number of ticks "
                               f"of {self.tick:g} s{self._lines.also_set(('tick',))}")])
        return ticks

    def spec(self, name: str) -> FmuSpec | PythonSpec:
        """The spec of a component or source (sources as PythonSpec) by name."""
        specs: dict[str, FmuSpec | PythonSpec] = {**self.fmu_components(),
                                                  **self.python_components()}
        if name not in specs:
            raise ScenarioError(self._file, [Problem("components", None, (
                f"no component named {name!r} (known: {', '.join(sorted(specs))})"))])
        return specs[name]

    def period_ticks(self, name: str, default_period: float | None = None) -> int:
        """Ticks between two steps of a component or source.

        Args:
            name: the component's (or source's) name.
            default_period: period in seconds to use when the scenario names
                none (a Python class's `default_period`); None means every tick.
        Raises:
            ScenarioError: if the period is not a whole multiple of the tick.
        """
        period = self.spec(name).period
        section = "sources" if name in self.sources else "components"
        if period is None and default_period is not None:
            period, note = default_period, " (the component's default period)"
        else:
            note = ""
        if period is None:
            return 1
        ticks = whole_ticks(period, self.tick)
        if ticks is None or ticks < 1:
            raise ScenarioError(self._file, [self.problem((section, name, "period"), (
                f"period {period:g} s{note} is not a whole multiple of tick {self.tick:g} s"
                f"{self._lines.also_set(('tick',))}"))])
        return ticks

    def fmu_components(self) -> dict[str, FmuSpec]:
        """The components given by an FMU, in file order."""
        return {n: s for n, s in self.components.items() if isinstance(s, FmuSpec)}

    def python_components(self) -> dict[str, PythonSpec]:
        """The Python components, then one PythonSpec per source, in file order."""
        result = {n: s for n, s in self.components.items() if isinstance(s, PythonSpec)}
        for name, source in self.sources.items():
            params = source.model_dump(mode="json", exclude={"kind", "period", "host"})
            result[name] = PythonSpec(python=SOURCE_CLASSES[source.kind], period=source.period,
                                      parameters=params, host=source.host)
        return result

    def plant_parameters(self, name: str, defaults: dict[str, float] | None = None
                         ) -> dict[str, float]:
        """Parameters of an FMU component with its uncertainty applied.

        Args:
            name: the FMU component's name.
            defaults: the FMU's own start values (from describe_fmu), needed
                when uncertainty names a parameter the scenario does not set.
        Returns:
            every parameter the scenario sets or perturbs -> value for the plant.
        """
        spec = self.fmu_components().get(name)
        if spec is None:
            raise ScenarioError(self._file, [Problem("components", None,
                                                     f"no FMU component named {name!r}")])
        values = dict(spec.parameters)
        for param, error in spec.uncertainty.items():
            base = values.get(param, (defaults or {}).get(param))
            if base is None or not math.isfinite(base):
                raise ScenarioError(self._file, [self.problem(
                    ("components", name, "uncertainty", param),
                    f"uncertainty on {param!r}, which has no value in parameters "
                    "nor a start value in the FMU")])
            values[param] = error.apply(base)
        return values

    def resolve_fmu_path(self, spec: FmuSpec) -> Path | str:
        """A built-in FMU name as is, or the .fmu path resolved against the YAML's folder."""
        if spec.fmu in BUILTIN_FMUS:
            return spec.fmu
        path = Path(spec.fmu)
        return path if path.is_absolute() else self.base_dir / path
