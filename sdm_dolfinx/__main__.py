from sdm_dolfinx.cli import main

raise SystemExit(main())
