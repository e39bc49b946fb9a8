"""The ground: errors, statistics, reproducibility and macro-action arrays; these import nothing else of famarl_cli."""
