"""``python -m components.build``: build every FMU of the project into fmus/."""

from components.build.project_fmus import main

raise SystemExit(main())
