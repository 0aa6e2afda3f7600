%%%
  VERSION:1
  LANGUAGE:ENGLISH
%%%

MODULE cam_contour
  ! Offline-programming style: one inline robtarget per motion, S4/IRC5 .prg header.
  ! Written for postproc's samples.
  TASK PERS tooldata tSpindle:=[TRUE,[[0,0,180.5],[1,0,0,0]],[80,[0,0,120],[1,0,0,0],0,0,0]];
  TASK PERS wobjdata wFixture:=[FALSE,TRUE,"",[[1950,-120,640],[0.9961947,0,0,0.0871557]],[[10,5,0],[1,0,0,0]]];

  PROC contour()
    ConfL\Off;
    MoveJ [[0,0,150],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v1000,z20,tSpindle\WObj:=wFixture;
    MoveL [[120.000,0.000,-2.500],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[115.911,20.706,-2.600],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[103.923,40.000,-2.700],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[84.853,56.569,-2.800],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[60.000,69.282,-2.900],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[31.058,77.274,-3.000],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[0.000,80.000,-3.100],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[-31.058,77.274,-3.200],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[-60.000,69.282,-3.300],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[-84.853,56.569,-3.400],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[-103.923,40.000,-3.500],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[-115.911,20.706,-3.600],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[-120.000,0.000,-3.700],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[-115.911,-20.706,-3.800],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[-103.923,-40.000,-3.900],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[-84.853,-56.569,-4.000],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[-60.000,-69.282,-4.100],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[-31.058,-77.274,-4.200],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[-0.000,-80.000,-4.300],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[31.058,-77.274,-4.400],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[60.000,-69.282,-4.500],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[84.853,-56.569,-4.600],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[103.923,-40.000,-4.700],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[115.911,-20.706,-4.800],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveL [[120.000,-0.000,-4.900],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v50,z1,tSpindle\WObj:=wFixture;
    MoveC [[0,80,10],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],[[-120,0,10],[0,0,1,0],[-1,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v100,z5,tSpindle\WObj:=wFixture;
    MoveL Offs(CRobT(\Tool:=tSpindle\WObj:=wFixture),0,0,100),v200,fine,tSpindle\WObj:=wFixture;
  ENDPROC
ENDMODULE
