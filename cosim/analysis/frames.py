"""A run's signals as pandas DataFrames, with units, for the Python API (`cosim.Run`).

The values are signals.csv's exactly (parsed as float64 by `RunData`, the
same numbers the metrics see). `signals_frame` is indexed by time ("time", s),
one column per "component.signal"; `df.attrs["units"]` and
`df.attrs["descriptions"]` map each column to its unit and description from
the manifest's "signals" entry ("" when the run's manifest predates it).
`array_frames` gives each array signal (arrays/<component>.<signal>.csv) a
frame indexed by its own sample times, columns "<signal>[i]". pandas is
imported only here.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from cosim.analysis.rundata import RunData

if TYPE_CHECKING:
    import pandas as pd


def _attrs(run: RunData, columns: list[str], base: dict[str, str] | None = None
           ) -> dict[str, Any]:
    entry = {c: run.signal_info(base[c] if base else c) for c in columns}
    return {"units": {c: str(e.get("unit", "")) for c, e in entry.items()},
            "descriptions": {c: str(e.get("description", "")) for c, e in entry.items()},
            "run_dir": str(run.run_dir)}


def signals_frame(run: RunData) -> pd.DataFrame:
    """The scalar signals: index time (s), columns "component.signal", units in attrs.

    Args:
        run: a loaded run folder (`cosim.analysis.rundata.load_run`).
    """
    import pandas as pd

    columns = list(run.columns)
    frame = pd.DataFrame({c: run.columns[c] for c in columns},
                         index=pd.Index(run.time, name="time"))
    frame.attrs.update(_attrs(run, columns))
    return frame


def array_frames(run: RunData) -> dict[str, pd.DataFrame]:
    """Each recorded array signal: name -> frame (index time, columns "name[i]"), units in attrs.

    Args:
        run: a loaded run folder.
    """
    import pandas as pd

    folder = run.run_dir / "arrays"
    names = sorted(p.stem for p in folder.glob("*.csv")) if folder.is_dir() else []
    frames = {}
    for name in names:
        array = run.array(name)
        if array is None:
            continue
        columns = [f"{name}[{i}]" for i in range(array.values.shape[1])]
        frame = pd.DataFrame(array.values, columns=columns,
                             index=pd.Index(array.times, name="time"))
        frame.attrs.update(_attrs(run, columns, {c: name for c in columns}))
        frames[name] = frame
    return frames
