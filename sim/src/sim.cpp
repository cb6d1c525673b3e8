int strut_sim_placeholder = 0;
