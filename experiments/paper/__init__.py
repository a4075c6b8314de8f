"""What ``make figures`` runs: one script per figure, table or ablation of the paper."""
