int strut_rig_placeholder = 0;
