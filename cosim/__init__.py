"""cosim: a co-simulation master for closed-loop vehicle control (FMU plants, Zenoh components)."""

import time as _time

__version__ = "0.1.0"

# When the package was first imported (perf_counter, CPU seconds): the start-up clock's
# fallback zero for a process that was forked long before it exec'd Python (cosim.engine.startup).
IMPORTED_AT = (_time.perf_counter(), _time.process_time())
