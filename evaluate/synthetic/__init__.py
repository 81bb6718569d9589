"""The seed's synthetic study on analytic edges with exact truth: ``study.py`` runs it, ``claims.py`` checks the seed's claims, ``figures.py`` draws them."""
