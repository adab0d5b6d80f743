from glint.cli import main

raise SystemExit(main())
