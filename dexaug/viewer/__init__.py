"""The interactive 3D grasp viewer: a dataset's grasps on the object, in a browser.

:mod:`dexaug.viewer.scene` turns a table into plain data (hand posed by forward kinematics of the
hand model, contacts, table, palm cloud), :mod:`dexaug.viewer.page` writes it with the WebGL
page (``static/``) as one HTML file. The pipeline writes ``viewer.html`` beside each
``report.html``; ``dexaug view GRASPS.h5`` writes one for any dataset.
"""
