from feedlog.cli import main

raise SystemExit(main())
