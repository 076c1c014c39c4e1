"""``python -m casadical`` and the ``casadical`` command: the command line in a process of its own.

The signal handlers go in first (:func:`casadical.runtime._interrupts.command_process`):
a Ctrl-C or SIGTERM while Python still imports the commands is one line
and exit 130/143 too, as is one that comes while the process ends.
"""


def run() -> None:
    """The ``casadical`` command."""
    from .runtime import _interrupts as interrupts

    interrupts.command_process()
    from .cli import main

    try:
        code = main()
    except SystemExit as e:        # --help, --version
        code = e.code if isinstance(e.code, int) else 0 if e.code is None else 1
    interrupts.end_process(code)


if __name__ == "__main__":
    run()
