"""``python -m casadical`` and the ``casadical`` command: the command line in a process of its own.

The signal handlers go in first (:func:`casadical.interrupts.command_process`):
a Ctrl-C or SIGTERM while Python still imports the commands is one line
and exit 130/143 too, as is one that comes while the process ends.
"""


def run() -> None:
    """The ``casadical`` command."""
    from . import interrupts

    interrupts.command_process()
    from .cli import main

    interrupts.end_process(main())


if __name__ == "__main__":
    run()
