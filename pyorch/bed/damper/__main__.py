"""``python -m pyorch.bed.damper RUN_DIR``: the thesis' fit (eq. 5.12) of a damper run's fall."""
from pyorch.bed.damper.cli import main

raise SystemExit(main())
