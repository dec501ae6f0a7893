"""FMUs as components: building the built-in plant FMUs, reading and checking an FMU's interface, hosting it in-process (fmpy) or on a worker.
"""
