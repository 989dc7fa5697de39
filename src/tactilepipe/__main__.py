from tactilepipe.cli.main import main

raise SystemExit(main())
