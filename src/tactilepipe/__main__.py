from tactilepipe.cli import main

raise SystemExit(main())
