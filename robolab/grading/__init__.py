"""The autograder: notebook loading, isolated execution, scoring, reports, release and export."""
