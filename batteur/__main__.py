from batteur.cli import main

raise SystemExit(main())
