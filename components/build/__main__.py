"""``python -m components.build``: build every FMU of the project into its FMU folder (--help names it)."""

from mre_common.guard import quiet_interrupts

quiet_interrupts()  # Ctrl-C or SIGTERM during the imports below: one line, exit 130, no traceback

from components.build.project_fmus import main  # noqa: E402

raise SystemExit(main())
