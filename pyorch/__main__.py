from pyorch.cli import main

raise SystemExit(main())
