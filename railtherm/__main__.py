from railtherm.cli import main

raise SystemExit(main())
