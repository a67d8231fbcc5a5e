"""The report: leaderboards as CSV (``leaderboard``), the paper's figures (``figures``) and
the self-contained HTML page (``report_html``).
"""
