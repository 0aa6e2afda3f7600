MODULE weld_cell
  ! RobotStudio style: data declared at the top of the module, motions move to names.
  ! Written for postproc's tests and samples.
  PERS tooldata tWeld:=[TRUE,[[0,0,200],[1,0,0,0]],[5,[0,0,100],[1,0,0,0],0,0,0]];
  TASK PERS wobjdata wTable:=[FALSE,TRUE,"",[[1800,-300,600],[0.707106781,0,0,0.707106781]],[[0,0,0],[1,0,0,0]]];
  CONST robtarget pHome:=[[1600,0,1200],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p10:=[[150.5,200,50],[0,0.7071068,0.7071068,0],[0,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p20:=[[250,200,50],[0,0.7071068,0.7071068,0],[0,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget pCirc:=[[300,250,50],[0,0.7071068,0.7071068,0],[0,-1,0,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget pEnd:=[[350,300,50],[0,0.7071068,0.7071068,0],[0,-1,0,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget seam{3}:=[[[100,-50,40.25],[0,0,1,0],[0,0,-1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],
                           [[140,-50,40.25],[0,0,1,0],[0,0,-1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],
                           [[180,-45,40.25],[0,0,1,0],[0,0,-1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]];
  VAR num i:=0;

  PROC main()
    MoveJ pHome, v1000, z50, tWeld;
    MoveJ Offs(p10,0,0,100), v1000, z20, tWeld\WObj:=wTable;
    MoveL p10, v200, fine, tWeld\WObj:=wTable;
    MoveL p20, v100, z1, tWeld\WObj:=wTable;
    MoveC pCirc, pEnd, v100, z1, tWeld\WObj:=wTable;
    MoveL RelTool(pEnd,0,0,-50), v500, z10, tWeld\WObj:=wTable;
    FOR i FROM 1 TO 3 DO
      MoveL seam{i}, v100, z1, tWeld\WObj:=wTable;  ! every element, in this frame
    ENDFOR
    MoveAbsJ [[0,0,0,0,90,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]\NoEOffs, v1000, fine, tool0;
  ENDPROC
ENDMODULE
