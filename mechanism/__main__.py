from mechanism.cli import main

raise SystemExit(main())
