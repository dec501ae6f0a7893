"""Scenario schema of the signal sources (disturbances: wind gusts, friction changes).

Each entry of a scenario's `sources:` section becomes a Python component of
`cosim.sources` named by its key, with one output port `value`. The fields of
a source, except `kind`, `period` and `host`, are the keyword arguments of its
component class, so the two stay in step (a test checks it).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Union

from pydantic import (BaseModel, ConfigDict, Discriminator, Field, PositiveFloat, Tag,
                      model_validator)

STRICT = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)  # no bool or str as numbers
#: a [abscissa, value] pair: YAML gives a list, which strict mode would refuse as a tuple
Point = Annotated[tuple[float, float], Field(strict=False)]


class SourceBase(BaseModel):
    """Fields every source has."""

    model_config = STRICT
    period: PositiveFloat | None = Field(None, description=(
        "time between two steps, a whole multiple of tick, s (null: every master tick)"))
    host: str = Field("local", min_length=1, description="'local' (the master's host), 'inproc' "
                                                         "(the master's own process) or the name of a "
                                                         "worker that runs it")
    unit: str = Field("", description="unit of the output 'value' ('' matches any unit)")


class ConstantSource(SourceBase):
    """value(t) = value."""

    kind: Literal["constant"] = Field(description="value(t) = value")
    value: float = Field(description="the output, in the source's unit")


class StepSource(SourceBase):
    """value(t) = initial for t < at, final for t >= at."""

    kind: Literal["step"] = Field(description="value(t) = initial before at, final from at on")
    initial: float = Field(description="the output before at, in the source's unit")
    final: float = Field(description="the output from at on, in the source's unit")
    at: float = Field(description="switch time, s")


class RampSource(SourceBase):
    """start until t_start, then linear to end at t_end, then end."""

    kind: Literal["ramp"] = Field(description="start until t_start, linear to end at t_end, "
                                              "then end")
    start: float = Field(description="the output until t_start, in the source's unit")
    end: float = Field(description="the output from t_end on, in the source's unit")
    t_start: float = Field(description="start of the ramp, s")
    t_end: float = Field(description="end of the ramp, after t_start, s")

    @model_validator(mode="after")
    def _ordered(self) -> RampSource:
        if not self.t_end > self.t_start:
            raise ValueError(f"t_end ({self.t_end}) must be after t_start ({self.t_start})")
        return self


class GustSource(SourceBase):
    """1-cos gust: base + amplitude/2 (1 - cos(2 pi (t - start)/duration)) inside the gust."""

    kind: Literal["gust"] = Field(description="1-cos gust: base + amplitude/2 (1 - cos(2 pi "
                                              "(t - start) / duration)) inside the gust")
    amplitude: float = Field(description="peak over base, mid-gust, in the source's unit")
    start: float = Field(description="onset of the gust, s")
    duration: PositiveFloat = Field(description="length of the gust, s")
    base: float = Field(0.0, description="the output outside the gust, in the source's unit")


class TableSource(SourceBase):
    """A value tabulated over time or over travelled distance."""

    kind: Literal["table"] = Field(description="a value tabulated over time or over "
                                               "travelled distance")
    over: Literal["time", "distance"] = Field("time", description=(
        "abscissa: 'time' (s) or 'distance' (m travelled by the point connected to inputs x, y)"))
    points: list[Point] = Field(min_length=1, description=(
        "[[abscissa, value], ...], abscissas strictly increasing (s or m; value in the "
        "source's unit); the first and last values hold outside"))
    interpolation: Literal["linear", "previous"] = Field("linear", description=(
        "'linear', or 'previous' (the value of the last point at or before the abscissa)"))

    @model_validator(mode="after")
    def _increasing(self) -> TableSource:
        for i in range(1, len(self.points)):
            if not self.points[i][0] > self.points[i - 1][0]:
                raise ValueError(
                    f"point {i} abscissa {self.points[i][0]} is not greater than "
                    f"point {i - 1} abscissa {self.points[i - 1][0]}: abscissas must "
                    "strictly increase")
        return self


SOURCE_MODELS: dict[str, type[SourceBase]] = {
    "constant": ConstantSource,
    "step": StepSource,
    "ramp": RampSource,
    "gust": GustSource,
    "table": TableSource,
}

#: kind -> "module:Class" of the component that implements it.
SOURCE_CLASSES: dict[str, str] = {
    "constant": "cosim.sources:Constant",
    "step": "cosim.sources:Step",
    "ramp": "cosim.sources:Ramp",
    "gust": "cosim.sources:Gust",
    "table": "cosim.sources:Table",
}

SOURCE_KIND_ERROR = "source_kind"


def _source_tag(value: Any) -> str | None:
    """Discriminate a source by its `kind` field; None when missing or unknown."""
    kind = value.get("kind") if isinstance(value, dict) else getattr(value, "kind", None)
    return f"<{kind}>" if isinstance(kind, str) and kind in SOURCE_MODELS else None


SourceSpec = Annotated[
    Union[tuple(Annotated[model, Tag(f"<{kind}>")] for kind, model in SOURCE_MODELS.items())],
    Discriminator(
        _source_tag,
        custom_error_type=SOURCE_KIND_ERROR,
        custom_error_message="kind must be one of " + ", ".join(SOURCE_MODELS),
    ),
]
